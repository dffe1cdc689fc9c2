from django.apps import AppConfig


class PortalConfig(AppConfig):
    name = "robotarium_portal"
    verbose_name = "Robotarium"
    default_auto_field = "django.db.models.BigAutoField"
