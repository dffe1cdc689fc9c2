"""The job queue's broker: django-q2's ORM broker (the queue is a table of the service's database), which
also keeps which worker slot took each job (models.TaskHold).

django-q2's cluster takes a job off the queue by locking its row until now + `retry`, and takes the next
one while its worker is busy (its pusher); nothing says who holds a lock. A slot killed outright (its
machine gone) would leave its jobs locked until `retry` ran out: a verification it had taken but not begun
waited 12 minutes in the service soak. With the holder kept, the watcher that finds the slot lost (or a
serve that finds it dead at its start) unlocks its jobs at once (TaskHold.release_tasks). A job handed out
again never runs twice at a time: the job claims its experiment by a conditional UPDATE (jobs.py)."""
from time import sleep

from django.db import DatabaseError, transaction
from django.utils import timezone
from django_q.brokers.orm import ORM
from django_q.conf import Conf

from robotarium_portal.database import database_retry


class HoldingORM(ORM):
    def dequeue(self):
        from robotarium_portal import jobs
        from robotarium_portal.models import TaskHold
        rows = self.get_connection()
        tasks = rows.filter(key=self.list_key, lock__lt=timezone.now())[0:Conf.BULK]
        if not tasks:
            sleep(Conf.POLL)   # (as the ORM broker: an empty queue spares the CPU)
            return None
        worker = jobs.me()
        taken = []
        for task in tasks:
            try:
                with transaction.atomic(using=Conf.ORM):   # the lock and its holder, or neither
                    if not rows.filter(id=task.id, lock=task.lock).update(lock=self.timeout(task)):
                        continue   # another cluster took it first
                    if worker is not None:
                        TaskHold.objects.update_or_create(task_id=task.id, defaults={"worker_id": worker})
            except DatabaseError:
                # Cut off while taking it (a database restart): whether the take was committed is not known, and if
                # it was, the job would stay locked for `retry` s by this slot, which never got it. What this slot
                # holds of it goes back on the queue (nothing, if the take was not committed).
                if worker is not None:
                    database_retry(lambda task=task: TaskHold.release_tasks([worker], tasks=[task.id]),
                                   "giving back job %s, taken while the database went away" % task.id)
                raise   # (django-q's pusher starts again)
            taken.append((task.pk, task.payload))
        return taken
