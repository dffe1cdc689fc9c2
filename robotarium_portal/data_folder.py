"""The service's data folder: made, with its secret key, before Django starts (settings make nothing).

serve, the worker and the tests call prepare(); the settings only read the key (read_secret_key)."""
import os
import secrets
from pathlib import Path

SECRET_KEY_FILE = "secret_key"


def prepare(data):
    """The data folder (0700: the service's alone, no job's script may read it) and its secret key, made
    once per service and kept there (never in the repository). Returns the folder."""
    data = Path(data).resolve()
    data.mkdir(parents=True, exist_ok=True)
    data.chmod(0o700)
    path = data / SECRET_KEY_FILE
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    except FileExistsError:
        return data
    with os.fdopen(fd, "w") as f:
        f.write(secrets.token_urlsafe(50))
    return data


def read_secret_key(data):
    try:
        return (Path(data) / SECRET_KEY_FILE).read_text().strip()
    except OSError:
        return ""
