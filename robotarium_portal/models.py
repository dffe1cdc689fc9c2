"""What the service keeps: who may use it (Profile beside Django's User) and the experiments."""
from django.conf import settings
from django.db import models
from django.utils import timezone


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

    def __str__(self):
        return "%s <%s>" % (self.name, self.user.email)

    @property
    def may_submit(self):
        return self.email_confirmed and self.approved and self.user.is_active


class Experiment(models.Model):
    SAVED, SUBMITTED, VERIFYING, REJECTED = "saved", "submitted", "verifying", "rejected"
    QUEUED, RUNNING, COMPLETED, FAILED = "queued", "running", "completed", "failed"
    STATES = [(s, s) for s in (SAVED, SUBMITTED, VERIFYING, REJECTED, QUEUED, RUNNING, COMPLETED, FAILED)]
    PENDING = (SUBMITTED, VERIFYING, QUEUED, RUNNING)   # counted against the per-user cap
    DONE = (REJECTED, COMPLETED, FAILED)                 # the "Completed Experiments" tab

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

    class Meta:
        ordering = ["-created"]

    def __str__(self):
        return "#%d %s (%s)" % (self.pk or 0, self.title, self.state)

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

    def settings_dict(self):
        """The settings .json the guide's Create Experiment page offers."""
        return {"title": self.title, "description": self.description,
                "estimated_duration": self.estimated_duration, "number_of_robots": self.number_of_robots,
                "main_file": self.main_file, "files": self.file_names()}

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
