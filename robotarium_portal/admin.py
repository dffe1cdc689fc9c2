from django.contrib import admin, messages

from robotarium_portal import mail
from robotarium_portal.models import Experiment, ExperimentFile, Profile, ReturnMessage, Worker


@admin.register(Profile)
class ProfileAdmin(admin.ModelAdmin):
    list_display = ("name", "user", "institute", "email_confirmed", "approved")
    list_filter = ("approved", "email_confirmed")
    actions = ["approve"]

    @admin.action(description="Approve the selected accounts")
    def approve(self, request, queryset):
        for profile in queryset.filter(approved=False).select_related("user"):
            if profile.approve(request.user):
                mail.try_sending(mail.send_approved, profile.user)


class FileInline(admin.TabularInline):
    model = ExperimentFile
    extra = 0


class ReturnMessageInline(admin.StackedInline):
    model = ReturnMessage
    extra = 1


@admin.register(Experiment)
class ExperimentAdmin(admin.ModelAdmin):
    """Every experiment; "state: queued" (or submitted, verifying, running) is the queue, and the selected ones
    may be cancelled (a running one is stopped by its worker within a heartbeat)."""
    list_display = ("pk", "title", "owner", "state", "worker", "submitted_at", "queued_at", "finished_at",
                    "differs_from_verification")
    list_filter = ("state",)
    inlines = [FileInline, ReturnMessageInline]
    actions = ["cancel"]

    @admin.action(description="Cancel the selected experiments (queued or running)")
    def cancel(self, request, queryset):
        done = [e for e in queryset if e.cancel(request.user.email or request.user.username)]
        for experiment in done:
            mail.try_sending(mail.send_issues_found, experiment)
        if done:
            self.message_user(request, "Cancelled %s." % ", ".join("#%d" % e.pk for e in done))
        if len(done) < queryset.count():
            self.message_user(request, "%d of the selected experiments were neither queued nor running: left as "
                              "they were." % (queryset.count() - len(done)), messages.WARNING)


@admin.register(Worker)
class WorkerAdmin(admin.ModelAdmin):
    """The workers' job slots: which host, since when, what they do, how many jobs, their last heartbeat."""
    list_display = ("host", "pid", "kind", "domain", "state", "alive_since", "current_job", "jobs_done",
                    "last_heartbeat")
    list_filter = ("state", "kind", "host")
    readonly_fields = [f.name for f in Worker._meta.fields]

    def has_add_permission(self, request):
        return False   # a worker registers itself when it starts
