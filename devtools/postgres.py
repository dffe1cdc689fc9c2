"""A PostgreSQL server of a test's or a benchmark's own: initdb into a folder, pg_ctl on a free port,
trust authentication for one user; stopped and removed afterwards. Debian's server binaries
(/usr/lib/postgresql/N/bin; ./robotarium test installs the `postgresql` package where it can)."""
import glob
import os
import pwd
import shutil
import socket
import subprocess
import tempfile


def server_binaries():
    """The folder with initdb and pg_ctl (the newest version), or None."""
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"), key=lambda p: int(p.split("/")[-3]))
    return os.path.dirname(found[-1]) if found else None


def free_port(host="127.0.0.1"):
    with socket.socket() as s:
        s.bind((host, 0))
        return s.getsockname()[1]


class PostgreSQL:
    """initdb + pg_ctl start as the unprivileged `postgres` account (PostgreSQL refuses to run as root)."""

    def __init__(self, listen=("127.0.0.1",), port=None, user="robotarium", database="robotarium"):
        self.bin = server_binaries()
        if self.bin is None:
            raise FileNotFoundError("no PostgreSQL server binaries (/usr/lib/postgresql/*/bin): apt-get install "
                                    "postgresql, or ./robotarium test, which installs it where it can")
        self.folder = tempfile.mkdtemp(prefix="robotarium-postgres-")
        self.data = os.path.join(self.folder, "data")
        self.listen, self.port, self.user, self.database = list(listen), port or free_port(), user, database
        self.as_user = []
        if os.geteuid() == 0:
            try:
                account = pwd.getpwnam("postgres")
            except KeyError:
                raise FileNotFoundError("PostgreSQL runs as an unprivileged account, and there is no `postgres` "
                                        "account here (Debian's postgresql package makes it)") from None
            os.chown(self.folder, account.pw_uid, account.pw_gid)
            self.as_user = ["runuser", "-u", "postgres", "--"]
        self._run("initdb", "-D", self.data, "-U", user, "--auth=trust", "-E", "UTF8", "--no-sync")
        with open(os.path.join(self.data, "postgresql.conf"), "a") as f:
            f.write("\nlisten_addresses = '%s'\nport = %d\nunix_socket_directories = '%s'\nfsync = off\n"
                    "max_connections = 200\n"
                    # what a failure's log needs: who waited for a lock, and for how long, and slow statements
                    "log_lock_waits = on\nlog_min_duration_statement = 1000\nlog_line_prefix = '%%m [%%p] %%a: '\n"
                    % (",".join(self.listen), self.port, self.folder))
        with open(os.path.join(self.data, "pg_hba.conf"), "a") as f:
            f.write("host all all 0.0.0.0/0 trust\n")   # the test's own private addresses only listen
        self.start()
        self._run("createdb", "-h", self.folder, "-p", str(self.port), "-U", user, database)

    def _run(self, tool, *args):
        result = subprocess.run(self.as_user + [os.path.join(self.bin, tool), *args], stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True, timeout=120)
        if result.returncode:
            raise RuntimeError("%s failed: %s" % (tool, result.stdout))
        return result.stdout

    def url(self, host=None):
        return "postgresql://%s@%s:%d/%s" % (self.user, host or self.listen[0], self.port, self.database)

    def start(self):
        self._run("pg_ctl", "-D", self.data, "-l", os.path.join(self.folder, "log.txt"), "-w", "-t", "60", "start")

    def stop(self, mode="fast"):
        self._run("pg_ctl", "-D", self.data, "-m", mode, "-w", "-t", "60", "stop")

    def restart(self):
        """Every connection is cut (fast shutdown), then the server answers again."""
        self.stop()
        self.start()

    def log(self, tail=4000):
        """The end of the server's log (its lock waits and slow statements, the restart)."""
        try:
            with open(os.path.join(self.folder, "log.txt"), errors="replace") as f:
                return f.read()[-tail:]
        except OSError as error:
            return "(no log: %s)" % error

    def query(self, sql, *params):
        import psycopg
        with psycopg.connect(self.url(), connect_timeout=10) as connection:
            return connection.execute(sql, params).fetchall()

    def close(self):
        if os.path.exists(os.path.join(self.data, "postmaster.pid")):
            try:
                self._run("pg_ctl", "-D", self.data, "-m", "immediate", "-w", "-t", "60", "stop")
            except RuntimeError:
                pass
        shutil.rmtree(self.folder, ignore_errors=True)
