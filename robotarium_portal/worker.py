"""One worker of ./robotarium serve: a django-q2 cluster (python -m robotarium_portal.worker verify|runs).

It holds serve's lifeline (robotarium_core.lifeline): should serve die, however it dies (kill -9
included), the worker stops its job's ./robotarium (which ends its experiment and writes its results)
and then itself, so no worker outlives its service; the experiment runs again at the next start."""
import os
import signal
import sys


def main():
    name = sys.argv[1]
    os.environ["Q_CLUSTER_NAME"] = name
    os.environ.setdefault("DJANGO_SETTINGS_MODULE", "robotarium_portal.settings")
    import django
    django.setup()
    from django.core.management import call_command

    from robotarium_core import lifeline
    from robotarium_portal import tasks

    def serve_is_gone():
        tasks.stop_jobs()
        os.kill(os.getpid(), signal.SIGTERM)   # the cluster's own stop: its worker ends, then the cluster

    lifeline.watch(serve_is_gone, name="serve")
    call_command("qcluster")


if __name__ == "__main__":
    main()
