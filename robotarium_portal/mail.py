"""The service's mail: the confirmation link, approval or refusal, "issues found" and "completed" (Django's
mail: SMTP when configured, else files in the data folder's mail/). Every link in it is built from the one
configured base URL, settings.PORTAL_URL (serve's --url; default the address serve listens on)."""
import logging

from django.conf import settings
from django.contrib.auth.tokens import PasswordResetTokenGenerator
from django.core.mail import send_mail
from django.urls import reverse
from django.utils.encoding import force_bytes
from django.utils.http import urlsafe_base64_encode

logger = logging.getLogger("robotarium_portal")


def try_sending(send, *args):
    """send(*args); a mail server that fails is logged, never a broken page or job. Whether it went."""
    try:
        send(*args)
        return True
    except Exception as error:   # noqa: BLE001 - SMTP and socket errors alike
        logger.error("could not send mail (%s): %s", send.__name__, error)
        return False


class ConfirmationTokens(PasswordResetTokenGenerator):
    """Django's signed, expiring tokens; a confirmed address makes its old links void."""
    key_salt = "robotarium_portal.mail.ConfirmationTokens"

    def _make_hash_value(self, user, timestamp):
        return "%s%s%s%s" % (user.pk, user.email, timestamp, user.profile.email_confirmed)


confirmation_tokens = ConfirmationTokens()


def link(name, *args):
    """The absolute address of the page `name` (a URL name), from the configured base URL."""
    return settings.PORTAL_URL + reverse(name, args=args)


def send_confirmation(user):
    send_mail("Robotarium: confirm your email address",
              "Hello %s,\n\nplease confirm your address for the Robotarium by opening this link:\n\n%s\n\n"
              "An administrator then approves your account; after that you can submit experiments.\n"
              % (user.profile.name if hasattr(user, "profile") else "",
                 link("confirm", urlsafe_base64_encode(force_bytes(user.pk)), confirmation_tokens.make_token(user))),
              settings.DEFAULT_FROM_EMAIL, [user.email])


def send_existing_account(user):
    """Someone signed up with an address that has an account: its owner hears of it (the page said nothing)."""
    send_mail("Robotarium: you have an account already",
              "Hello,\n\nsomeone (you?) tried to sign up for the Robotarium with this address, which has an account "
              "already. Log in at %s, or, if you forgot your password, set a new one at %s.\n\nIf it was not you, "
              "nothing changed: you may ignore this mail.\n" % (link("login"), link("password_reset")),
              settings.DEFAULT_FROM_EMAIL, [user.email])


def send_refused(profile):
    send_mail("Robotarium: your account was not approved",
              "Hello %s,\n\nan administrator did not approve your Robotarium account, for this reason:\n\n%s\n\n"
              "Write to the administrators if you think this is a mistake; an account may be approved later.\n\n%s\n"
              % (profile.name, profile.refusal_reason, link("dashboard")),
              settings.DEFAULT_FROM_EMAIL, [profile.user.email])


def _experiment_link(experiment):
    return link("experiment", experiment.pk)


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


def tell_administrators_of_a_difference(experiment, in_run, verified):
    """A run whose safety layer changed commands its verification never needed changed: the
    administrators hear of it, with both figures."""
    from django.contrib.auth import get_user_model
    staff = list(get_user_model().objects.filter(is_staff=True, is_active=True).exclude(email="")
                 .values_list("email", flat=True))
    if staff:
        send_mail("Robotarium: experiment #%d behaved differently on the robots than in verification" % experiment.pk,
                  "Experiment #%d \"%s\" of %s: the safety layer changed %d command arrays in its run that the "
                  "verification's certificate would have changed too, and %d in its verification. The script may "
                  "behave differently when it is verified.\n\n%s\n"
                  % (experiment.pk, experiment.title, experiment.owner.email, in_run, verified,
                     _experiment_link(experiment)),
                  settings.DEFAULT_FROM_EMAIL, staff)


def send_approved(user):
    send_mail("Robotarium: your account is approved",
              "Hello %s,\n\nan administrator approved your Robotarium account: you can submit experiments now.\n\n%s\n"
              % (user.profile.name, link("dashboard")),
              settings.DEFAULT_FROM_EMAIL, [user.email])


def tell_administrators(user):
    """A confirmed account waits for approval: the administrators hear of it."""
    from django.contrib.auth import get_user_model
    staff = list(get_user_model().objects.filter(is_staff=True, is_active=True).exclude(email="")
                 .values_list("email", flat=True))
    if staff:
        send_mail("Robotarium: %s waits for approval" % user.email,
                  "%s (%s, %s) confirmed their address and waits for approval:\n\n%s\n"
                  % (user.profile.name, user.profile.institute, user.email,
                     link("approvals")),
                  settings.DEFAULT_FROM_EMAIL, staff)
