from django.contrib import admin
from django.utils import timezone

from robotarium_portal import mail
from robotarium_portal.models import Experiment, ExperimentFile, Profile, ReturnMessage


@admin.register(Profile)
class ProfileAdmin(admin.ModelAdmin):
    list_display = ("name", "user", "institute", "email_confirmed", "approved")
    list_filter = ("approved", "email_confirmed")
    actions = ["approve"]

    @admin.action(description="Approve the selected accounts")
    def approve(self, request, queryset):
        for profile in queryset.filter(approved=False).select_related("user"):
            profile.approved, profile.approved_at, profile.approved_by = True, timezone.now(), request.user
            profile.save(update_fields=["approved", "approved_at", "approved_by"])
            mail.try_sending(mail.send_approved, profile.user)


class FileInline(admin.TabularInline):
    model = ExperimentFile
    extra = 0


class ReturnMessageInline(admin.StackedInline):
    model = ReturnMessage
    extra = 1


@admin.register(Experiment)
class ExperimentAdmin(admin.ModelAdmin):
    list_display = ("pk", "title", "owner", "state", "submitted_at", "finished_at")
    list_filter = ("state",)
    inlines = [FileInline, ReturnMessageInline]
