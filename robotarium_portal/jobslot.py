"""One job slot of a worker (robotarium_portal.supervisor.Supervisor): a django-q2 cluster
(python -m robotarium_portal.jobslot verify|runs), one job at a time, on its slot's testbed.

It holds its supervisor's lifeline (robotarium_core.lifeline): should the supervisor die, however it dies
(kill -9 included), the slot stops its job's ./robotarium (which ends its experiment and writes its
results) and then itself, so no slot outlives its supervisor; the watchers decide the experiment's fate."""
import multiprocessing
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
    from robotarium_portal import jobbox, jobs

    warm = []

    def supervisor_is_gone():
        jobs.stop_jobs()
        for process in warm:
            jobbox.stop_group(process.pid, grace=10)
        os.kill(os.getpid(), signal.SIGTERM)   # the cluster's own stop: its worker ends, then the cluster

    lifeline.watch(supervisor_is_gone, name="supervisor")
    # The slot's warm testbed (a root service): started before the cluster's workers, which inherit where it is;
    # stopped with the slot (and, should the slot die outright, by its parent-death signal).
    warm += [p for p in [jobs.start_warm_testbed(name)] if p is not None]
    try:
        call_command("qcluster")   # returns once the cluster runs (its sentinel, a child, does the work)
        for child in multiprocessing.active_children():
            child.join()   # until the cluster has stopped
    finally:
        for process in warm:
            jobbox.stop_group(process.pid, grace=10)


if __name__ == "__main__":
    main()
