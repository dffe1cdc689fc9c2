"""Sign-up, the email confirmation, the administrators' approval (log in/out and password reset are Django's)."""
from django import forms
from django.contrib import messages
from django.contrib.admin.views.decorators import staff_member_required
from django.contrib.auth import get_user_model
from django.contrib.auth.forms import AuthenticationForm
from django.shortcuts import get_object_or_404, redirect, render
from django.utils.encoding import force_str
from django.utils.http import urlsafe_base64_decode
from django.views.decorators.http import require_POST

from robotarium_portal import mail
from robotarium_portal.forms import SignUpForm
from robotarium_portal.models import Profile


class EmailLoginForm(AuthenticationForm):
    username = forms.EmailField(label="Email", widget=forms.EmailInput(attrs={"autofocus": True}))

    def clean_username(self):
        return self.cleaned_data["username"].strip().lower()


def signup(request):
    form = SignUpForm(request.POST or None)
    if request.method == "POST" and form.is_valid():
        user = form.save()
        sent = mail.try_sending(mail.send_confirmation, request, user)
        return render(request, "portal/signup_done.html", {"email": user.email, "sent": sent})
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
            mail.try_sending(mail.send_confirmation, request, user)
        # The same answer either way: the page does not tell who has an account.
        messages.info(request, "If an unconfirmed account has this address, a new link is on its way.")
        return redirect("login")
    return render(request, "portal/resend.html", {"form": form})


@staff_member_required
def approvals(request):
    waiting = Profile.objects.filter(approved=False).select_related("user").order_by("user__date_joined")
    return render(request, "portal/approvals.html", {"waiting": waiting})


@staff_member_required
@require_POST
def approve(request, pk):
    profile = get_object_or_404(Profile, pk=pk)
    if profile.approve(request.user):
        mail.try_sending(mail.send_approved, profile.user)
    messages.success(request, "Approved %s (%s)." % (profile.name, profile.user.email))
    return redirect("approvals")
