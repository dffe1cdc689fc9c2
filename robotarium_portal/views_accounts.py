"""Sign-up, the email confirmation, the administrators' approval or refusal, the account page and its API
tokens (log in/out and password reset are Django's, log-in limited by django-axes)."""
from django import forms
from django.conf import settings
from django.contrib import messages
from django.contrib.admin.views.decorators import staff_member_required
from django.contrib.auth import get_user_model
from django.contrib.auth import views as auth_views
from django.contrib.auth.decorators import login_required
from django.contrib.auth.forms import AuthenticationForm
from django.shortcuts import get_object_or_404, redirect, render
from django.utils.encoding import force_str
from django.utils.http import urlsafe_base64_decode
from django.views.decorators.http import require_POST

from robotarium_portal import mail
from robotarium_portal.forms import SignUpForm
from robotarium_portal.models import ApiToken, Profile


def login_name(request, credentials=None):
    """The account a log-in names, as the log-in form reads it (django-axes counts failures by it)."""
    source = credentials if credentials is not None else request.POST
    return (source.get("username") or "").strip().lower()


class EmailLoginForm(AuthenticationForm):
    username = forms.EmailField(label="Email", widget=forms.EmailInput(attrs={"autofocus": True}))
    # The same words whether the address has an account or not.
    error_messages = dict(AuthenticationForm.error_messages,
                          invalid_login="The email or the password is wrong (forgot your password? Set a new one "
                                        "with the link below).")

    def clean_username(self):
        return self.cleaned_data["username"].strip().lower()


def signup(request):
    """The same answer whether the address has an account or not (no enumeration): a new account gets its
    confirmation link, an existing one's owner a mail saying that someone tried."""
    form = SignUpForm(request.POST or None)
    if request.method == "POST" and form.is_valid():
        if form.existing_user is not None:
            sent = mail.try_sending(mail.send_existing_account, form.existing_user)
            email = form.existing_user.email
        else:
            user = form.save()
            sent = mail.try_sending(mail.send_confirmation, user)
            email = user.email
        return render(request, "portal/signup_done.html", {"email": email, "sent": sent})
    return render(request, "portal/signup.html", {"form": form})


def confirm(request, uidb64, token):
    try:
        user = get_user_model().objects.get(pk=int(force_str(urlsafe_base64_decode(uidb64))))
    except (ValueError, TypeError, OverflowError, get_user_model().DoesNotExist):
        user = None
    valid = user is not None and hasattr(user, "profile") and mail.confirmation_tokens.check_token(user, token)
    if valid:
        user.profile.email_confirmed = True
        user.profile.save(update_fields=["email_confirmed"])
        if not user.profile.approved:
            mail.try_sending(mail.tell_administrators, user)
    return render(request, "portal/confirmed.html", {"valid": valid, "confirmed_user": user if valid else None},
                  status=200 if valid else 400)


class ResendForm(forms.Form):
    email = forms.EmailField()


def resend(request):
    form = ResendForm(request.POST or None)
    if request.method == "POST" and form.is_valid():
        user = get_user_model().objects.filter(username=form.cleaned_data["email"].strip().lower()).first()
        if user is not None and hasattr(user, "profile") and not user.profile.email_confirmed:
            mail.try_sending(mail.send_confirmation, user)
        # The same answer either way: the page does not tell who has an account.
        messages.info(request, "If an unconfirmed account has this address, a new link is on its way.")
        return redirect("login")
    return render(request, "portal/resend.html", {"form": form})


class PasswordResetView(auth_views.PasswordResetView):
    """Django's reset (the same answer for any address), its link from the one configured base URL."""
    email_template_name = "registration/password_reset_email.txt"

    def form_valid(self, form):
        self.extra_email_context = {"portal_url": settings.PORTAL_URL}
        return super().form_valid(form)


@staff_member_required
def approvals(request):
    waiting = Profile.objects.filter(approved=False, refused_at=None).select_related("user").order_by(
        "user__date_joined")
    return render(request, "portal/approvals.html", {"waiting": waiting})


@staff_member_required
@require_POST
def approve(request, pk):
    profile = get_object_or_404(Profile, pk=pk)
    if request.POST.get("refuse") is not None:
        reason = request.POST.get("reason", "").strip()[:2000]
        if not reason:
            messages.error(request, "Write the reason for refusing %s (it is mailed to them)." % profile.user.email)
        elif profile.refuse(request.user, reason):
            mail.try_sending(mail.send_refused, profile)
            messages.success(request, "Refused %s (%s); the reason was mailed." % (profile.name, profile.user.email))
        return redirect("approvals")
    if profile.approve(request.user):
        mail.try_sending(mail.send_approved, profile.user)
    messages.success(request, "Approved %s (%s)." % (profile.name, profile.user.email))
    return redirect("approvals")


@login_required
def account(request):
    """The person's account: who they are, and their API tokens (a new one shown once)."""
    key = None
    if request.method == "POST":
        if request.POST.get("action") == "new-token":
            _, key = ApiToken.make(request.user)
        elif request.POST.get("action") == "delete-token":
            ApiToken.objects.filter(user=request.user, pk=request.POST.get("token") or 0).delete()
            messages.success(request, "The token was deleted: it opens nothing any more.")
            return redirect("account")
    return render(request, "portal/account.html", {"tokens": request.user.api_tokens.all(), "new_key": key,
                                                   "portal_url": settings.PORTAL_URL})
