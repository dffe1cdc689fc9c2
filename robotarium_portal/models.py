"""What the service keeps: who may use it (Profile beside Django's User, ApiToken), the experiments and
their state machine (Experiment's transitions), the workers' job slots (Worker)."""
import hashlib
import secrets

from django.conf import settings
from django.db import models
from django.db.models import Exists, F, Q
from django.utils import timezone

from robotarium_core import run_record

ANY = object()   # a transition that holds for whichever worker holds the experiment


def _now_text(when=None):
    return (when or timezone.now()).strftime("%Y-%m-%d %H:%M:%S UTC")


def without_nul(value):
    """`value` (text, or JSON made of dicts, lists and text) with every NUL character as U+FFFD:
    PostgreSQL's text and jsonb take no NUL, and a job's output may hold some (a run's output
    file written on past a truncation is zero-filled), which failed the whole job (DataError)."""
    if isinstance(value, str):
        return value.replace("\x00", "\ufffd")
    if isinstance(value, dict):
        return {without_nul(k): without_nul(v) for k, v in value.items()}
    if isinstance(value, list):
        return [without_nul(v) for v in value]
    return value


class Profile(models.Model):
    """The guide's sign-up fields, and the two gates before an account may submit."""
    user = models.OneToOneField(settings.AUTH_USER_MODEL, on_delete=models.CASCADE, related_name="profile")
    name = models.CharField(max_length=150)
    city = models.CharField(max_length=100)
    state = models.CharField(max_length=100)
    institute = models.CharField(max_length=200)
    reason = models.TextField("reason for using the Robotarium", max_length=2000)
    email_confirmed = models.BooleanField(default=False)
    approved = models.BooleanField(default=False)
    approved_at = models.DateTimeField(null=True, blank=True)
    approved_by = models.ForeignKey(settings.AUTH_USER_MODEL, null=True, blank=True, on_delete=models.SET_NULL,
                                    related_name="+")
    refused_at = models.DateTimeField(null=True, blank=True)
    refusal_reason = models.TextField(max_length=2000, blank=True)   # mailed to the person

    def __str__(self):
        return "%s <%s>" % (self.name, self.user.email)

    @property
    def may_submit(self):
        return self.email_confirmed and self.approved and self.user.is_active

    def approve(self, by):
        """An administrator approves the account (once: True when it was waiting)."""
        if not Profile.objects.filter(pk=self.pk, approved=False).update(approved=True, approved_at=timezone.now(),
                                                                          approved_by=by, refused_at=None):
            return False
        self.refresh_from_db()
        return True

    def refuse(self, by, reason):
        """An administrator refuses the account, with a reason mailed to its owner (once; it may be approved
        later all the same)."""
        if not Profile.objects.filter(pk=self.pk, approved=False, refused_at=None).update(
                refused_at=timezone.now(), refusal_reason=reason, approved_by=by):
            return False
        self.refresh_from_db()
        return True


class ApiToken(models.Model):
    """A person's key to the JSON API (./robotarium submit): only its SHA-256 is kept, the key itself is shown
    once when it is made. It acts as its owner: the same accounts, permissions and 404s as the pages."""
    PREFIX = "rbt_"
    user = models.ForeignKey(settings.AUTH_USER_MODEL, on_delete=models.CASCADE, related_name="api_tokens")
    digest = models.CharField(max_length=64, unique=True)
    shown = models.CharField(max_length=16)   # its first characters, to tell tokens apart on the account page
    created = models.DateTimeField(default=timezone.now)
    last_used = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["-created"]

    @staticmethod
    def _digest(key):
        return hashlib.sha256(key.encode()).hexdigest()

    @classmethod
    def make(cls, user):
        """(the token, its key: shown once, kept nowhere)."""
        key = cls.PREFIX + secrets.token_urlsafe(32)
        return cls.objects.create(user=user, digest=cls._digest(key), shown=key[:12]), key

    @classmethod
    def user_of(cls, key):
        """The active user whose key this is, or None."""
        token = cls.objects.filter(digest=cls._digest(key or "")).select_related("user").first()
        if token is None or not token.user.is_active:
            return None
        cls.objects.filter(pk=token.pk).update(last_used=timezone.now())
        return token.user


class Experiment(models.Model):
    SAVED, SUBMITTED, VERIFYING, REJECTED = "saved", "submitted", "verifying", "rejected"
    QUEUED, RUNNING, COMPLETED, FAILED = "queued", "running", "completed", "failed"
    CANCELLED = "cancelled"   # by an administrator
    STATES = [(s, s) for s in (SAVED, SUBMITTED, VERIFYING, REJECTED, QUEUED, RUNNING, COMPLETED, FAILED, CANCELLED)]
    PENDING = (SUBMITTED, VERIFYING, QUEUED, RUNNING)   # submitted, not finished: counted against the per-user cap
    DONE = (REJECTED, COMPLETED, FAILED, CANCELLED)      # finished: the "Completed Experiments" tab
    EDITABLE = (SAVED, REJECTED, FAILED, CANCELLED)      # its owner may change it and submit it (again)

    owner = models.ForeignKey(settings.AUTH_USER_MODEL, on_delete=models.CASCADE, related_name="experiments")
    title = models.CharField(max_length=200)
    description = models.TextField(max_length=5000, blank=True)
    estimated_duration = models.PositiveIntegerField("estimated duration (s)")
    number_of_robots = models.PositiveIntegerField()
    main_file = models.CharField(max_length=100, blank=True)
    state = models.CharField(max_length=20, choices=STATES, default=SAVED)
    detail = models.TextField(blank=True)          # why: the rejection's rules, a failure's cause
    verification = models.JSONField(null=True, blank=True)   # ./robotarium verify --json, as it answered
    run_outcome = models.CharField(max_length=40, blank=True)   # run.json's outcome
    results = models.CharField(max_length=500, blank=True)   # the run folder, relative to the experiment's
    attempts = models.PositiveIntegerField(default=0)         # runs started (a service restart runs it again)
    timings = models.JSONField(default=dict, blank=True)      # s the verify and run commands took
    created = models.DateTimeField(default=timezone.now)
    submitted_at = models.DateTimeField(null=True, blank=True)
    queued_at = models.DateTimeField(null=True, blank=True)
    started_at = models.DateTimeField(null=True, blank=True)
    finished_at = models.DateTimeField(null=True, blank=True)
    # The worker that holds it while verifying or running (claimed together with the state).
    worker = models.ForeignKey("Worker", null=True, blank=True, on_delete=models.SET_NULL, related_name="experiments")

    class Meta:
        ordering = ["-created"]

    def __str__(self):
        return "#%d %s (%s)" % (self.pk or 0, self.title, self.state)

    def save(self, *args, **kwargs):
        # What jobs write comes from files a script's run made: no NUL may reach the database.
        self.detail, self.verification = without_nul(self.detail), without_nul(self.verification)
        super().save(*args, **kwargs)

    @property
    def folder(self):
        return settings.EXPERIMENTS_DIR / str(self.pk)

    @property
    def files_dir(self):
        return self.folder / "files"

    @property
    def results_dir(self):
        return self.folder / self.results if self.results else None

    def file_names(self):
        return sorted(f.name for f in self.files.all())

    # -- the state machine: every change of state is one of these methods, each one conditional UPDATE
    # (state X -> Y only where the row is still in X, and held by `worker` where one is named), so two
    # workers, a job handed out twice or an administrator's cancel never both win. True when it changed.

    def _transition(self, sources, target, worker=ANY, unless=None, claimer=None, **fields):
        """claimer: the slot taking the experiment (its worker_id), which must not have been found lost: one
        found lost while it was cut off from the database takes nothing (its supervisor starts it afresh)."""
        rows = Experiment.objects.filter(pk=self.pk, state__in=sources)
        if worker is not ANY:
            rows = rows.filter(worker=worker)
        if claimer is not None:
            rows = rows.exclude(Exists(Worker.found_lost(claimer)))
        if unless is not None:
            rows = rows.exclude(unless)
        fields = {k: without_nul(v) for k, v in fields.items()}
        if not rows.update(state=target, **fields):
            return False
        self.refresh_from_db()
        return True

    def submit(self):
        """Saved (or finished: submitted again) -> submitted, its earlier outcome cleared."""
        return self._transition(self.EDITABLE, self.SUBMITTED, detail="", submitted_at=timezone.now(), results="",
                                run_outcome="", verification=None, worker_id=None, finished_at=None)

    def claim_verification(self, worker):
        """Submitted -> verifying, held by worker; not while another of its owner's is verified (one
        verification slot a person at a time: one person's submissions never hold every slot)."""
        return self._transition([self.SUBMITTED], self.VERIFYING, worker_id=worker, claimer=worker,
                                unless=Q(owner__experiments__state=self.VERIFYING))

    @classmethod
    def claim_next_run(cls, worker):
        """The oldest queued experiment (first come, first served) -> running, held by worker; None if none."""
        while True:
            experiment = cls.objects.filter(state=cls.QUEUED).order_by("queued_at", "pk").first()
            if experiment is None:
                return None
            if experiment._transition([cls.QUEUED], cls.RUNNING, worker_id=worker, claimer=worker,
                                      started_at=timezone.now(), attempts=F("attempts") + 1):
                return experiment
            if worker is not None and Worker.found_lost(worker).exists():
                return None   # this slot was found lost: it takes none
            # another worker took it first: the next

    def queue(self, worker, verification, timings):
        """Verified and accepted -> queued (keeping its place: queued_at is set once, a requeue keeps it)."""
        return self._transition([self.VERIFYING], self.QUEUED, worker, queued_at=timezone.now(),
                                verification=verification, timings=timings, detail="", worker_id=None)

    def reject(self, worker, detail, verification, timings):
        """Verifying -> rejected: the rules it broke."""
        return self._transition([self.VERIFYING], self.REJECTED, worker, detail=detail, verification=verification,
                                timings=timings, finished_at=timezone.now(), worker_id=None)

    def fail(self, worker, detail, **fields):
        """Verifying or running -> failed, with why (and what was recorded: results, run_outcome, timings)."""
        return self._transition([self.VERIFYING, self.RUNNING], self.FAILED, worker, detail=detail,
                                finished_at=timezone.now(), **fields, worker_id=None)

    def complete(self, worker, detail, **fields):
        """Running -> completed, with its results."""
        return self._transition([self.RUNNING], self.COMPLETED, worker, detail=detail, finished_at=timezone.now(),
                                **fields, worker_id=None)

    def cancel(self, by):
        """An administrator cancels it while it waits or works (a running one is stopped by its worker)."""
        return self._transition(self.PENDING, self.CANCELLED, finished_at=timezone.now(),
                                detail="Cancelled by an administrator (%s) at %s." % (by, _now_text()))

    def requeue(self, worker, why, when=None):
        """Its worker stopped (a service stopped, a worker lost) at `when` (default now): a run goes back to the
        head of the queue (its queued_at kept) and runs again from the start; a verification is made again."""
        at = _now_text(when)
        if self.state == self.RUNNING:
            detail = "%s during run %d (at %s); the experiment runs again from the start." % (why, self.attempts, at)
            return self._transition([self.RUNNING], self.QUEUED, worker, detail=detail, worker_id=None)
        return self._transition([self.VERIFYING], self.SUBMITTED, worker, worker_id=None,
                                detail="%s during its verification (at %s); it is verified again." % (why, at))

    def keep_results(self, **fields):
        """A cancelled run's job ended later: what it recorded stays attached (the state stays cancelled)."""
        return bool(Experiment.objects.filter(pk=self.pk, state=self.CANCELLED).update(**fields))

    # -- what it is

    def differs_from_verification(self):
        """(arrays the run's safety layer changed that a verification's certificate would have changed
        too, arrays the verification's certificate would have changed) when the first is more than 0
        and the second 0: a script that behaves differently on the robots than in verification (one
        that stays still while verified and drives robots head-on in the run). Else None."""
        counts = (self.verification or {}).get("counts") or {}
        run = run_record.read(str(self.results_dir)) if self.results_dir else None
        if run is None:
            return None
        in_run, verified = run.ideal_interventions, counts.get("safety_interventions")
        if in_run and verified == 0:
            return in_run, verified
        return None

    def settings_dict(self):
        """The settings .json the guide's Create Experiment page offers."""
        return {"title": self.title, "description": self.description,
                "estimated_duration": self.estimated_duration, "number_of_robots": self.number_of_robots,
                "main_file": self.main_file, "files": self.file_names()}

    @property
    def verified_api(self):
        """The Robotarium API its verification ran the script with: "guide", "2" (the 2.x simulator's), or ""
        (not verified, or verified before the verdict named it)."""
        return (self.verification or {}).get("api") or ""

    def place_in_queue(self):
        """1 for the next to run; None when not queued."""
        if self.state != self.QUEUED:
            return None
        return Experiment.objects.filter(state=self.QUEUED, queued_at__lt=self.queued_at).count() + 1


class ExperimentFile(models.Model):
    experiment = models.ForeignKey(Experiment, on_delete=models.CASCADE, related_name="files")
    name = models.CharField(max_length=100)
    size = models.PositiveIntegerField()

    class Meta:
        unique_together = [("experiment", "name")]
        ordering = ["name"]


class ReturnMessage(models.Model):
    """Feedback from the staff on an experiment (the results page's "Return Messages")."""
    experiment = models.ForeignKey(Experiment, on_delete=models.CASCADE, related_name="return_messages")
    author = models.ForeignKey(settings.AUTH_USER_MODEL, null=True, on_delete=models.SET_NULL, related_name="+")
    text = models.TextField(max_length=5000)
    created = models.DateTimeField(default=timezone.now)

    class Meta:
        ordering = ["created"]


class Worker(models.Model):
    """One job slot of a worker (./robotarium worker or serve's own): it verifies or runs one job at a time on a
    testbed of its own (ROS_DOMAIN_ID `domain` on `host`). Its supervisor beats for it every
    settings.WORKER_HEARTBEAT s; one whose beats stopped is found lost (robotarium_portal.supervisor.sweep)."""
    VERIFY, RUNS = "verify", "runs"
    ALIVE, STOPPED, LOST = "alive", "stopped", "lost"
    host = models.CharField(max_length=200)
    pid = models.PositiveIntegerField()           # its supervisor's process on host
    kind = models.CharField(max_length=10, choices=[(VERIFY, "verification"), (RUNS, "runs")])
    domain = models.PositiveIntegerField(null=True)
    state = models.CharField(max_length=10, default=ALIVE, choices=[(s, s) for s in (ALIVE, STOPPED, LOST)])
    alive_since = models.DateTimeField(default=timezone.now)
    last_heartbeat = models.DateTimeField(default=timezone.now)
    beats = models.PositiveBigIntegerField(default=0)   # what a watcher compares: no clock of two machines
    current_job = models.CharField(max_length=200, blank=True)
    jobs_done = models.PositiveIntegerField(default=0)
    ended_at = models.DateTimeField(null=True, blank=True)

    class Meta:
        ordering = ["-alive_since"]

    def __str__(self):
        return "%s pid %d (%s, domain %s)" % (self.host, self.pid, self.kind, self.domain)

    @classmethod
    def found_lost(cls, pk):
        """Slot `pk`, where it was found lost (a queryset: empty while it is not)."""
        return cls.objects.filter(pk=pk, state=cls.LOST)


class TaskHold(models.Model):
    """Which worker slot's cluster took a job off the queue (django-q2's OrmQ row, locked for the cluster's
    `retry`), while the job is there: robotarium_portal.broker writes it in the same transaction as the lock,
    and the job's row takes it along when it goes (acknowledged, or the queue rebuilt). A slot found lost or
    stopped gives its jobs back at once (release_tasks), taken or not yet begun, instead of after `retry`
    (1800 s for a verification); a live slot's jobs keep their lock."""
    task = models.OneToOneField("django_q.OrmQ", on_delete=models.CASCADE, primary_key=True, related_name="+")
    worker = models.ForeignKey(Worker, on_delete=models.CASCADE, related_name="+")

    @classmethod
    def release_tasks(cls, worker_pks, tasks=None):
        """The jobs these slots took off the queue (of them, `tasks` where given) go back on it now (unlocked);
        returns how many."""
        from django_q.models import OrmQ
        rows = cls.objects.filter(worker__in=worker_pks)
        if tasks is not None:
            rows = rows.filter(task__in=tasks)
        held = list(rows.values_list("task_id", flat=True))
        freed = OrmQ.objects.filter(pk__in=held).update(lock=timezone.now())
        cls.objects.filter(task__in=held, worker__in=worker_pks).delete()
        return freed
