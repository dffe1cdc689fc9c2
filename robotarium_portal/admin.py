from django.contrib import admin
from django.utils import timezone

from robotarium_portal.models import Experiment, ExperimentFile, Profile, ReturnMessage


@admin.register(Profile)
class ProfileAdmin(admin.ModelAdmin):
    list_display = ("name", "user", "institute", "email_confirmed", "approved")
    list_filter = ("approved", "email_confirmed")
    actions = ["approve"]

    @admin.action(description="Approve the selected accounts")
    def approve(self, request, queryset):
        queryset.update(approved=True, approved_at=timezone.now(), approved_by=request.user)


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
