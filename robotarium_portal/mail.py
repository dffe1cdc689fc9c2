"""The service's mail: the confirmation link, "issues found" and "completed" (Django's mail: SMTP when
configured, else files in the data folder's mail/)."""
from django.conf import settings
from django.contrib.auth.tokens import PasswordResetTokenGenerator
from django.core.mail import send_mail
from django.urls import reverse
from django.utils.encoding import force_bytes
from django.utils.http import urlsafe_base64_encode


class ConfirmationTokens(PasswordResetTokenGenerator):
    """Django's signed, expiring tokens; a confirmed address makes its old links void."""
    key_salt = "robotarium_portal.mail.ConfirmationTokens"

    def _make_hash_value(self, user, timestamp):
        return "%s%s%s%s" % (user.pk, user.email, timestamp, user.profile.email_confirmed)


confirmation_tokens = ConfirmationTokens()


def send_confirmation(request, user):
    path = reverse("confirm", args=[urlsafe_base64_encode(force_bytes(user.pk)), confirmation_tokens.make_token(user)])
    link = request.build_absolute_uri(path)
    send_mail("Robotarium: confirm your email address",
              "Hello %s,\n\nplease confirm your address for the Robotarium by opening this link:\n\n%s\n\n"
              "An administrator then approves your account; after that you can submit experiments.\n"
              % (user.profile.name, link),
              settings.DEFAULT_FROM_EMAIL, [user.email])


def _experiment_link(experiment):
    return settings.PORTAL_URL + reverse("experiment", args=[experiment.pk])


def send_issues_found(experiment):
    send_mail("Robotarium: issues found in experiment #%d \"%s\"" % (experiment.pk, experiment.title),
              "Your experiment #%d \"%s\" was not run:\n\n%s\n\nIts page: %s\n"
              % (experiment.pk, experiment.title, experiment.detail, _experiment_link(experiment)),
              settings.DEFAULT_FROM_EMAIL, [experiment.owner.email])


def send_completed(experiment):
    send_mail("Robotarium: experiment #%d \"%s\" has completed" % (experiment.pk, experiment.title),
              "Your experiment #%d \"%s\" has completed.\n\n%s\n\nThe results (video, scripts, data files, "
              "log files): %s\n" % (experiment.pk, experiment.title, experiment.detail, _experiment_link(experiment)),
              settings.DEFAULT_FROM_EMAIL, [experiment.owner.email])
