"""Writing to the service's database through a restart of it (robotarium_portal.jobs and .supervisor)."""
import logging
import time

logger = logging.getLogger("robotarium_portal")
DATABASE_PATIENCE = 600  # s a job keeps trying to write its outcome while the database does not answer


def database_retry(action, what):
    """action() on a fresh connection; while the database does not answer (a restart), again every second
    for DATABASE_PATIENCE s. What a job writes at its end is never lost to a database that was away."""
    from django.db import InterfaceError, OperationalError, close_old_connections, connection
    deadline = time.monotonic() + DATABASE_PATIENCE
    while True:
        close_old_connections()
        try:
            return action()
        except (OperationalError, InterfaceError) as error:
            connection.close()
            if time.monotonic() > deadline:
                raise
            logger.warning("the database did not answer while %s (%s); trying again", what, error)
            time.sleep(1.0)
