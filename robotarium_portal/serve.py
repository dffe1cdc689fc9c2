"""./robotarium serve: the portal (waitress, a WSGI server) and its own worker (django-q2 clusters:
"verify" and "runs", robotarium_portal.supervisor) on this machine, everything kept in one data folder and
its database (SQLite there, or PostgreSQL with --database, for workers on other machines). Stop it
(Ctrl-C) and start it again: the experiments' states are in the database, the jobs are made again from them."""
import argparse
import fcntl
import getpass
import os
import signal
import sys
import threading
from pathlib import Path

from robotarium_portal.supervisor import database_url

REPOSITORY = Path(__file__).resolve().parent.parent


def parse(argv):
    parser = argparse.ArgumentParser(
        prog="./robotarium serve",
        description="Run your own Robotarium: the web portal (accounts, experiments, verification, the queue, "
                    "results) and one worker, on this machine. Everything it keeps (SQLite database, "
                    "experiments, mail) is in the data folder.",
        epilog="First administrator: ./robotarium serve --create-admin you@example.org (asks for a password). "
               "Mail goes to DATA/mail/ (one file per message) unless ROBOTARIUM_SMTP_HOST (and "
               "ROBOTARIUM_SMTP_PORT, _USER, _PASSWORD, _TLS=1, ROBOTARIUM_MAIL_FROM) name an SMTP server. "
               "Workers on other machines: serve --database postgresql://..., then ./robotarium worker --help.")
    parser.add_argument("--data", default=str(REPOSITORY / "service"),
                        help="the service's folder (default: service/ in the repository); workers on other "
                             "machines need it too, on a shared path")
    parser.add_argument("--database", default="", type=database_url,
                        help="PostgreSQL for the service's state, postgresql://USER@HOST[:PORT]/NAME, for workers on "
                             "other machines (./robotarium worker); its password from PGPASSWORD or a password file "
                             "(PGPASSFILE, ~/.pgpass), never on the command line; default: SQLite in the data folder")
    parser.add_argument("--jobs", type=int, default=1,
                        help="verifications and runs at once on this machine (default 1 of each; 0: none here, "
                             "the workers run elsewhere)")
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1; 0.0.0.0: "
                        "every interface, then name the host the users type with --allowed-host)")
    parser.add_argument("--port", type=int, default=8000, help="port (default 8000; 0: any free one)")
    parser.add_argument("--url", help="the address people reach the portal at, the base of every link in its mail "
                        "(default: the address it listens on, e.g. http://127.0.0.1:8000)")
    parser.add_argument("--allowed-host", action="append", default=[],
                        help="a host name the portal answers to besides localhost (repeat for several)")
    parser.add_argument("--create-admin", metavar="EMAIL",
                        help="create (or make) an administrator account with this email, asking for its password "
                             "(read from standard input when it is not a terminal), then exit")
    parser.add_argument("--create-token", metavar="EMAIL",
                        help="make an API token for this approved account (administrators included; for "
                             "./robotarium submit), print it once, then exit")
    parser.add_argument("--run-domain", type=int, help="ROS_DOMAIN_ID of the runs' testbed (default: a free one)")
    parser.add_argument("--verify-domain", type=int,
                        help="ROS_DOMAIN_ID of the verification's testbed (default: a free one)")
    return parser.parse_args(argv)


def setup_django(data, database=""):
    from robotarium_portal.supervisor import setup_django as setup
    setup(data, database)


def create_admin(email):
    from django.contrib.auth import get_user_model
    from django.contrib.auth.password_validation import validate_password
    from django.core.exceptions import ValidationError

    from robotarium_portal.models import Profile
    email = email.strip().lower()
    if sys.stdin.isatty():
        password = getpass.getpass("Password for %s: " % email)
        if getpass.getpass("Password again: ") != password:
            sys.exit("[robotarium] error: the two passwords differ; nothing was changed")
    else:
        password = sys.stdin.readline().rstrip("\n")
    user = get_user_model().objects.filter(username=email).first() or get_user_model()(username=email, email=email)
    try:
        validate_password(password, user)
    except ValidationError as error:
        sys.exit("[robotarium] error: %s Nothing was changed." % " ".join(error.messages))
    user.is_staff = user.is_superuser = True
    user.set_password(password)
    user.save()
    Profile.objects.update_or_create(user=user, defaults={
        "name": "Administrator", "email_confirmed": True, "approved": True})
    print("[robotarium] %s is an administrator: log in at the portal; its admin pages are under /admin/" % email)


def create_token(email):
    """An API token for an approved account (an operator's way; a person makes theirs on the account page)."""
    from django.contrib.auth import get_user_model

    from robotarium_portal.models import ApiToken
    user = get_user_model().objects.filter(username=email.strip().lower()).select_related("profile").first()
    profile = getattr(user, "profile", None)
    if user is None or not user.is_active or not (user.is_staff or (profile is not None and profile.may_submit)):
        sys.exit("[robotarium] error: no approved account %s here (it signs up, confirms its address and is approved "
                 "first; an administrator is approved already)" % email)
    _, key = ApiToken.make(user)
    print("[robotarium] an API token for %s (shown this once; ./robotarium submit reads it from --token or "
          "ROBOTARIUM_TOKEN):\n%s" % (user.email, key))
    return 0


def main(argv=None):
    args = parse(argv)
    data = Path(args.data).resolve()
    data.mkdir(parents=True, exist_ok=True)
    lock = open(data / "serve.lock", "w")
    if args.create_admin is None and args.create_token is None:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            sys.exit("[robotarium] error: another ./robotarium serve uses %s (or the workers of one that was "
                     "stopped are still ending their jobs); stop it first, or give this one its own --data folder" % data)
    if args.jobs < 0:
        sys.exit("[robotarium] error: --jobs must be 0 or more")
    setup_django(data, args.database)
    from django.core.management import call_command
    from django.db import DatabaseError
    try:
        call_command("migrate", interactive=False, verbosity=0)
    except DatabaseError as error:
        sys.exit("[robotarium] error: cannot use the database %s (%s); check --database"
                 % (args.database.split("@")[-1] or "in " + str(data), str(error).strip()))
    if args.create_admin is not None:
        return create_admin(args.create_admin)
    if args.create_token is not None:
        return create_token(args.create_token)

    import waitress

    from robotarium_portal import jobs
    from robotarium_portal.supervisor import Stop, Supervisor, forget_dead_local_workers, stop_on_signals
    from robotarium_portal.wsgi import application
    forget_dead_local_workers()   # this machine's slots whose supervisor is gone hand their jobs back
    jobs.reconcile()   # before any worker: the jobs again from the experiments' states
    hosts = ["localhost", "127.0.0.1", "[::1]"] + args.allowed_host + (
        [args.host] if args.host not in ("0.0.0.0", "::") else [])
    try:
        server = waitress.create_server(application, host=args.host, port=args.port, threads=24)   # live streams hold one each
    except OSError as error:
        sys.exit("[robotarium] error: cannot listen on %s:%d (%s); choose another with --port (0: any free one)"
                 % (args.host, args.port, error.strerror or error))
    shown_host = args.allowed_host[0] if args.allowed_host else ("127.0.0.1" if args.host in ("0.0.0.0", "::")
                                                                 else args.host)
    url = "http://%s:%d/" % (shown_host, int(server.effective_port))
    base_url = (args.url or url).rstrip("/")   # every mail link, here and in the workers
    env = dict(os.environ, ROBOTARIUM_PORTAL_URL=base_url, ROBOTARIUM_PORTAL_HOSTS=",".join(hosts),
               PYTHONPATH=os.pathsep.join([str(REPOSITORY), os.environ.get("PYTHONPATH", "")]))
    os.environ.update({k: env[k] for k in ("ROBOTARIUM_PORTAL_URL", "ROBOTARIUM_PORTAL_HOSTS")})
    from django.conf import settings
    settings.ALLOWED_HOSTS, settings.PORTAL_URL = hosts, base_url
    workers = Supervisor(data, ["verify", "runs"] if args.jobs else [], args.jobs, env, lock=lock,
                         domains={"verify": args.verify_domain, "runs": args.run_domain})
    workers.start()
    mailer = settings.MAILERS["default"]
    mail = ("the SMTP server %s:%s" % (mailer["OPTIONS"]["host"], mailer["OPTIONS"]["port"])
            if mailer["BACKEND"].endswith("smtp.EmailBackend") else "%s (one file per message)" % settings.MAIL_DIR)
    print("[robotarium] the Robotarium portal is at %s" % url, flush=True)
    print("[robotarium] data (database, experiments, worker logs) in %s; mail goes to %s" % (data, mail), flush=True)
    database = (("PostgreSQL at %s" % args.database.split("@")[-1]) if args.database
                else "SQLite (%s)" % settings.DATABASES["default"]["NAME"])
    slots = ", ".join("%s on ROS_DOMAIN_ID %d" % (w.kind, w.domain) for w, _ in workers.slots)
    print("[robotarium] database: %s; here: %s; Ctrl-C stops it (nothing is lost)"
          % (database, slots or "no worker (./robotarium worker runs them elsewhere)"), flush=True)
    from robotarium_portal.jobbox import isolation
    print("[robotarium] %s" % isolation(), flush=True)   # what holds, and (not root) what does not
    from django.contrib.auth import get_user_model
    if not get_user_model().objects.filter(is_staff=True).exists():
        print("[robotarium] no administrator yet: ./robotarium serve --create-admin you@example.org%s"
              % ("" if args.data == str(REPOSITORY / "service") else " --data %s" % args.data), flush=True)

    stop_on_signals()

    def watch():
        while not workers.stopping.wait(2.0):   # a stop stops the workers: no error then
            if workers.dead() and not workers.stopping.is_set():
                print("[robotarium] error: the worker %s stopped (its log is in %s); stopping the service"
                      % (", ".join(workers.dead()), workers.logs), flush=True)
                os.kill(os.getpid(), signal.SIGTERM)
                return

    threading.Thread(target=watch, daemon=True).start()
    try:
        server.run()
    except Stop:
        pass
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
            signal.signal(sig, signal.SIG_IGN)   # the stop below is not cut short by a second Ctrl-C
        print("[robotarium] stopping the workers (a running experiment runs again at the next start)", flush=True)
        server.close()
        workers.stop()
        print("[robotarium] stopped", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
