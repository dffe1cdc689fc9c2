"""Django settings of the portal, read from the environment; importing them makes nothing.

Everything the service keeps lives under one data folder (ROBOTARIUM_PORTAL_DATA, default service/
in the repository): the SQLite database, the secret key, the experiments' files and results, and
outgoing mail (unless an SMTP server is configured). robotarium_portal.data_folder.prepare() makes
the folder and its secret key; serve, the worker and the tests call it before Django starts."""
import os
import sys
from datetime import timedelta
from pathlib import Path

from django.utils.csp import CSP

from robotarium_portal.data_folder import read_secret_key

REPOSITORY = Path(os.environ.get("ROBOTARIUM_ROOT") or Path(__file__).resolve().parent.parent)
DATA_DIR = Path(os.environ.get("ROBOTARIUM_PORTAL_DATA") or REPOSITORY / "service").resolve()
EXPERIMENTS_DIR = DATA_DIR / "experiments"
MAIL_DIR = DATA_DIR / "mail"
SECRET_KEY = read_secret_key(DATA_DIR)   # "" until prepare() made it: Django then refuses to sign anything
DEBUG = os.environ.get("ROBOTARIUM_PORTAL_DEBUG") == "1"
ALLOWED_HOSTS = [h for h in os.environ.get("ROBOTARIUM_PORTAL_HOSTS", "localhost,127.0.0.1,[::1]").split(",") if h]
# The one base URL of every link in mail (serve's --url; default the address serve listens on, which serve
# sets for itself and its workers).
PORTAL_URL = os.environ.get("ROBOTARIUM_PORTAL_URL", "http://127.0.0.1:8000").rstrip("/")

INSTALLED_APPS = [
    "robotarium_portal.apps.PortalConfig",   # first: its registration/ templates over the admin's
    "django.contrib.admin",
    "django.contrib.auth",
    "django.contrib.contenttypes",
    "django.contrib.sessions",
    "django.contrib.messages",
    "django.contrib.staticfiles",
    "django_q",
    "axes",
]
MIDDLEWARE = [
    "django.middleware.security.SecurityMiddleware",
    "django.contrib.sessions.middleware.SessionMiddleware",
    "django.middleware.common.CommonMiddleware",
    "django.middleware.csrf.CsrfViewMiddleware",
    "django.contrib.auth.middleware.AuthenticationMiddleware",
    "django.contrib.messages.middleware.MessageMiddleware",
    "django.middleware.clickjacking.XFrameOptionsMiddleware",
    "django.middleware.csp.ContentSecurityPolicyMiddleware",
    "axes.middleware.AxesMiddleware",   # last: it answers a locked-out log-in
]
# Django's own Content-Security-Policy: this site's scripts, styles, pictures and videos only (the page's
# <style> and <script> carry the request's nonce); no plug-ins, no framing, forms post here only.
SECURE_CSP = {
    "default-src": [CSP.SELF],
    "script-src": [CSP.SELF, CSP.NONCE],
    "style-src": [CSP.SELF, CSP.NONCE],
    "img-src": [CSP.SELF, "data:"],
    "media-src": [CSP.SELF],
    "connect-src": [CSP.SELF],
    "object-src": [CSP.NONE],
    "base-uri": [CSP.NONE],
    "frame-ancestors": [CSP.NONE],
    "form-action": [CSP.SELF],
}
ROOT_URLCONF = "robotarium_portal.urls"
TEMPLATES = [{
    "BACKEND": "django.template.backends.django.DjangoTemplates",
    "DIRS": [],
    "APP_DIRS": True,
    "OPTIONS": {"context_processors": [
        "django.template.context_processors.request",
        "django.contrib.auth.context_processors.auth",
        "django.contrib.messages.context_processors.messages",
        "django.template.context_processors.csp",
    ]},
}]
WSGI_APPLICATION = "robotarium_portal.wsgi.application"

# SQLite in WAL mode (the portal and the workers read and write at once); IMMEDIATE transactions take
# the write lock up front, so two writers wait for each other instead of failing.
DATABASES = {"default": {
    "ENGINE": "django.db.backends.sqlite3",
    "NAME": DATA_DIR / "portal.sqlite3",
    "OPTIONS": {"timeout": 30, "transaction_mode": "IMMEDIATE",
                "init_command": "PRAGMA journal_mode=WAL; PRAGMA synchronous=NORMAL;"},
}}
# PostgreSQL instead (--database postgresql://user[:password]@host[:port]/name): workers on other machines.
# CONN_MAX_AGE 0: a connection lives one request or one job step, so a database restart costs nothing but a
# retry (robotarium_portal.database.database_retry); the health check catches a connection a restart broke.
DATABASE_URL = os.environ.get("ROBOTARIUM_PORTAL_DATABASE", "")
if DATABASE_URL:
    from urllib.parse import unquote, urlsplit
    _url = urlsplit(DATABASE_URL)
    if _url.scheme not in ("postgresql", "postgres") or not _url.path.strip("/"):
        raise ValueError("--database %r: give postgresql://USER[:PASSWORD]@HOST[:PORT]/DATABASE" % DATABASE_URL)
    DATABASES = {"default": {
        "ENGINE": "django.db.backends.postgresql",
        "NAME": unquote(_url.path.strip("/")), "USER": unquote(_url.username or ""),
        "PASSWORD": unquote(_url.password or ""), "HOST": _url.hostname or "", "PORT": str(_url.port or ""),
        "CONN_MAX_AGE": 0, "CONN_HEALTH_CHECKS": True,
        # application_name: which process a connection is, in pg_stat_activity and the server's log
        "OPTIONS": {"connect_timeout": 10, "application_name": "robotarium %s pid %d" % (
            " ".join([os.path.basename(sys.argv[0])] + sys.argv[1:2])[:40], os.getpid())},
    }}
DEFAULT_AUTO_FIELD = "django.db.models.BigAutoField"

AUTH_PASSWORD_VALIDATORS = [
    {"NAME": "django.contrib.auth.password_validation.UserAttributeSimilarityValidator"},
    {"NAME": "django.contrib.auth.password_validation.MinimumLengthValidator"},
    {"NAME": "django.contrib.auth.password_validation.CommonPasswordValidator"},
    {"NAME": "django.contrib.auth.password_validation.NumericPasswordValidator"},
]
# Failed log-ins (django-axes): after AXES_FAILURE_LIMIT failures for one account, or from one address,
# log-in is refused for AXES_COOLOFF_TIME with a page that says so; a success or a password reset clears
# the count. The account is counted by its address as typed, lower case (as the log-in form reads it).
AUTHENTICATION_BACKENDS = ["axes.backends.AxesStandaloneBackend", "django.contrib.auth.backends.ModelBackend"]
AXES_FAILURE_LIMIT = 10
AXES_COOLOFF_TIME = timedelta(minutes=15)
AXES_LOCKOUT_PARAMETERS = ["username", "ip_address"]   # each on its own: per account, and per address
AXES_USERNAME_CALLABLE = "robotarium_portal.views_accounts.login_name"
AXES_LOCKOUT_TEMPLATE = "registration/locked_out.html"
AXES_RESET_ON_SUCCESS = True
AXES_VERBOSE = False
LOGIN_URL = "login"
LOGIN_REDIRECT_URL = "dashboard"
LOGOUT_REDIRECT_URL = "login"

LANGUAGE_CODE = "en-us"
TIME_ZONE = "UTC"
USE_I18N = False
USE_TZ = True
STATIC_URL = "static/"

# Mail: to a real SMTP server when ROBOTARIUM_SMTP_HOST is set, else one file per message in mail/.
DEFAULT_FROM_EMAIL = os.environ.get("ROBOTARIUM_MAIL_FROM", "robotarium@localhost")
if os.environ.get("ROBOTARIUM_SMTP_HOST"):
    MAILERS = {"default": {"BACKEND": "django.core.mail.backends.smtp.EmailBackend", "OPTIONS": {
        "host": os.environ["ROBOTARIUM_SMTP_HOST"], "port": int(os.environ.get("ROBOTARIUM_SMTP_PORT", "25")),
        "username": os.environ.get("ROBOTARIUM_SMTP_USER", ""),
        "password": os.environ.get("ROBOTARIUM_SMTP_PASSWORD", ""),
        "use_tls": os.environ.get("ROBOTARIUM_SMTP_TLS") == "1", "timeout": 30}}}
else:
    MAILERS = {"default": {"BACKEND": "django.core.mail.backends.filebased.EmailBackend",
                           "OPTIONS": {"file_path": str(MAIL_DIR)}}}

# Uploads: Django keeps small files in memory and larger ones in a temporary file; the request may be
# a little over the files' own total (the form's fields).
PORTAL_MAX_FILES = int(os.environ.get("ROBOTARIUM_PORTAL_MAX_FILES", "20"))
PORTAL_MAX_FILE_BYTES = int(os.environ.get("ROBOTARIUM_PORTAL_MAX_FILE_BYTES", str(5 * 1024 * 1024)))
PORTAL_MAX_PENDING = int(os.environ.get("ROBOTARIUM_PORTAL_MAX_PENDING", "3"))
# The form says how many are too many (up to this many in one request); past it, the portal's 400 page says so.
DATA_UPLOAD_MAX_NUMBER_FILES = 1000
DATA_UPLOAD_MAX_MEMORY_SIZE = 2 * 1024 * 1024
FILE_UPLOAD_MAX_MEMORY_SIZE = 2 * 1024 * 1024

# The jobs (django-q2, ORM broker: the queue is a table of this database; a job is claimed by a
# conditional UPDATE, so by one worker only). Two clusters: "verify" answers submissions while
# "runs" drives the testbed, one experiment at a time, first come first served.
# timeout: a run is stopped at the testbed's time limit (900 s) plus start and the results' video;
# retry (> timeout) is when a claimed job nobody finished is handed out again; a lost or stopped worker slot's
# jobs go back at once (broker_class keeps who took each job: models.TaskHold, supervisor.lost and release).
# poll: an idle slot looks at the queue every 0.1 s (0.5 ms of CPU each on SQLite): a submission waited 0.25 s on
# average at 0.5 s, twice on its way (to its verification, then to its run).
Q_CLUSTER = {
    "name": "runs",
    "orm": "default",
    "broker_class": "robotarium_portal.broker.HoldingORM",   # the ORM broker, keeping who took each job
    "workers": 1,
    "recycle": 50,
    "timeout": 1800,
    "retry": 2100,
    "max_attempts": 1,
    "ack_failures": True,
    "poll": 0.1,
    "catch_up": False,
    "save_limit": 200,
    "ALT_CLUSTERS": {"verify": {"timeout": 1500, "retry": 1800}},   # over the longest verification's limit
}
# A verification's wall-time limit: the verifier's own rule (1.5 x the declared duration) plus VERIFY_STARTUP s
# for its testbed and the script's imports (900 s declared: 1410 s). A script that spins or never ends is
# rejected at it, its rule named ("time"), and the next submission is verified.
VERIFY_STARTUP = float(os.environ.get("ROBOTARIUM_PORTAL_VERIFY_STARTUP", "60"))
# Each verification slot keeps a warm verification testbed (./robotarium up --verification --no-record) in a network
# namespace of its own, which each verification's box joins (jobs.start_warm_testbed); "0": none, each
# verification starts a testbed of its own in its box. A root service only (the boxes' namespaces).
WARM_VERIFICATION = os.environ.get("ROBOTARIUM_PORTAL_WARM_VERIFICATION", "1") != "0"
# The same for each run slot (not a worker of robots): ./robotarium up, recording into the data folder, each run's
# folder moved into its experiment's results at its end; "0": each run starts a testbed of its own in its box.
WARM_RUNS = os.environ.get("ROBOTARIUM_PORTAL_WARM_RUNS", "1") != "0"
# Each worker beats every WORKER_HEARTBEAT s; one that missed WORKER_LOST_AFTER s of beats, while the one
# who watches saw the database all that time, is lost: its verification is handed out again, its run failed.
WORKER_HEARTBEAT = float(os.environ.get("ROBOTARIUM_WORKER_HEARTBEAT", "2"))
WORKER_LOST_AFTER = 5 * WORKER_HEARTBEAT
LOGGING = {
    "version": 1,
    "disable_existing_loggers": False,
    "handlers": {"console": {"class": "logging.StreamHandler"}},
    "loggers": {name: {"handlers": ["console"], "level": os.environ.get("ROBOTARIUM_PORTAL_LOG", "WARNING")}
                for name in ("django_q", "robotarium_portal")},
}

# Each job in its own box (robotarium_portal/jobbox.py, docs/portal.md): its folder under JOB_BOXES_DIR
# (outside the data folder, which no job may read), its script's limits.
JOB_BOXES_DIR = Path(os.environ.get("ROBOTARIUM_PORTAL_BOXES") or str(DATA_DIR) + "-boxes")
JOB_LIMITS = {
    "cpu_seconds": 1200,            # of the script's process: a 900 s run computing all the time, and then some
    "memory_bytes": 8 * 1024 ** 3,  # address space (rclpy, numpy and the DDS threads take ~1.5 GB of it)
    "file_bytes": 1024 ** 3,        # the largest file the script may write
    "processes": 512,               # processes and threads of the script's account (DDS makes ~20 a participant)
    "open_files": 1024,
    "disk_bytes": 2 * 1024 ** 3,    # the job's folder in all (watched), and each of its private tmpfs
}
