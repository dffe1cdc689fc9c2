"""Accounts as a careful service keeps them (issue 39): failed log-ins limited per account and per address
with a page that says so; no enumeration through sign-up, reset or log-in; an approval refused with a
reason mailed; every mail link from the one configured base URL; API tokens shown once."""
import itertools
import re

from django.conf import settings
from django.core import mail
from django.test import Client, override_settings

from robotarium_portal.models import ApiToken, Profile

PASSWORD = "a-long-Passphrase-7"
_n = itertools.count()


def person(approved=True, staff=False):
    from django.contrib.auth import get_user_model
    email = "acct%d@example.org" % next(_n)
    user = get_user_model().objects.create_user(username=email, email=email, password=PASSWORD, is_staff=staff)
    Profile.objects.create(user=user, name="Person", city="c", state="s", institute="i", reason="r",
                           email_confirmed=True, approved=approved)
    return user


def without_nonce(page):
    """The page without its Content-Security-Policy nonce (a new one each answer)."""
    return re.sub(r'nonce="[^"]*"', "", page)


def log_in(client, username, password, address="127.0.0.1"):
    return client.post("/login/", {"username": username, "password": password}, REMOTE_ADDR=address)


def test_failed_log_ins_are_limited_per_account_then_the_right_password_is_refused_too():
    user = person()
    client = Client()
    for _ in range(settings.AXES_FAILURE_LIMIT - 1):
        response = log_in(client, user.email.upper(), "wrong", address="10.9.0.%d" % next(_n))   # any case, anywhere
        assert response.status_code == 200 and b"The email or the password is wrong" in response.content
    locked = log_in(client, user.email, "wrong", address="10.9.1.1")
    assert locked.status_code == 429 and b"Too many failed log-ins" in locked.content
    assert b"15 minutes" in locked.content
    assert log_in(Client(), user.email, PASSWORD, address="10.9.2.2").status_code == 429   # the account is locked
    assert log_in(Client(), person().email, PASSWORD, address="10.9.3.3").status_code == 302   # others are not


def test_failed_log_ins_are_limited_per_address_across_accounts():
    address = "10.8.0.1"
    for _ in range(settings.AXES_FAILURE_LIMIT):
        log_in(Client(), "nobody%d@example.org" % next(_n), "wrong", address=address)
    assert log_in(Client(), person().email, PASSWORD, address=address).status_code == 429
    assert log_in(Client(), person().email, PASSWORD, address="10.8.0.2").status_code == 302


def test_sign_up_reset_and_log_in_do_not_tell_whether_an_address_has_an_account():
    existing = person()
    mail.outbox.clear()
    fields = {"password": PASSWORD, "confirmation": PASSWORD, "name": "E", "city": "c", "state": "s",
              "institute": "i", "reason": "r"}
    pages = [without_nonce(Client().post("/signup/", dict(fields, email=email)).content.decode().replace(email, "E"))
             for email in (existing.email, "fresh%d@example.org" % next(_n))]
    assert pages[0] == pages[1] and "Thank you for signing up" in pages[0]
    told = [m for m in mail.outbox if m.to == [existing.email]]
    assert len(told) == 1 and "you have an account already" in told[0].subject   # its owner hears of it
    resets = [without_nonce(Client().post("/password/reset/", {"email": e}, follow=True).content.decode())
              for e in (existing.email, "nobody%d@example.org" % next(_n))]
    assert resets[0] == resets[1]
    wrong = [log_in(Client(), e, "wrong", address="10.7.0.%d" % next(_n)).content.decode().replace(e, "EMAIL")
             for e in (existing.email, "nobody%d@example.org" % next(_n))]
    assert re.sub(r'value="[^"]+"', "", without_nonce(wrong[0])) == re.sub(r'value="[^"]+"', "", without_nonce(wrong[1]))


def test_an_administrator_refuses_an_account_with_a_reason_mailed_to_its_owner():
    waiting, admin = person(approved=False), person(staff=True)
    client = Client()
    client.force_login(admin)
    mail.outbox.clear()
    response = client.post("/staff/approvals/%d/" % waiting.profile.pk, {"refuse": "", "reason": ""}, follow=True)
    assert b"Write the reason" in response.content
    client.post("/staff/approvals/%d/" % waiting.profile.pk, {"refuse": "", "reason": "Not in the class <b>."})
    waiting.profile.refresh_from_db()
    assert waiting.profile.refused_at is not None and not waiting.profile.approved
    (message,) = mail.outbox
    assert message.to == [waiting.email] and "Not in the class <b>." in message.body
    assert "value=\"%s\"" % waiting.email not in client.get("/staff/approvals/").content.decode()   # not waiting
    page = Client()
    page.force_login(waiting)
    assert "Not in the class &lt;b&gt;." in page.get("/account/").content.decode()


@override_settings(PORTAL_URL="http://lab.example.org:8901")
def test_every_mail_link_starts_with_the_configured_base_url():
    admin = person(staff=True)
    mail.outbox.clear()
    Client().post("/signup/", {"email": "base%d@example.org" % next(_n), "password": PASSWORD,
                               "confirmation": PASSWORD, "name": "B", "city": "c", "state": "s", "institute": "i",
                               "reason": "r"})
    Client().post("/password/reset/", {"email": admin.email})
    waiting = person(approved=False)
    client = Client()
    client.force_login(admin)
    client.post("/staff/approvals/%d/" % waiting.profile.pk)
    links = [link for m in mail.outbox for link in re.findall(r"https?://\S+", m.body)]
    assert len(links) >= 3 and all(link.startswith("http://lab.example.org:8901/") for link in links), links


def test_an_api_token_is_shown_once_and_kept_as_its_digest_only():
    user = person()
    client = Client()
    client.force_login(user)
    page = client.post("/account/", {"action": "new-token"}).content.decode()
    key = re.search(r'id="new-token">(rbt_[\w-]+)<', page).group(1)
    token = ApiToken.objects.get(user=user)
    assert key not in (token.digest, token.shown) and ApiToken.user_of(key) == user
    assert key not in client.get("/account/").content.decode()   # shown once
    client.post("/account/", {"action": "delete-token", "token": token.pk})
    assert ApiToken.user_of(key) is None


def test_the_confirmed_page_offers_the_dashboard_to_a_logged_in_person():
    from robotarium_portal import mail as portal_mail
    user = person()
    Profile.objects.filter(user=user).update(email_confirmed=False)
    user.refresh_from_db()
    link = re.search(r"https?://[^/\s]+(/confirm/\S+/)", _mailed(portal_mail.send_confirmation, user)).group(1)
    client = Client()
    client.force_login(user)
    page = client.get(link).content.decode()
    assert "Go to your dashboard" in page and ">Log in<" not in page


def _mailed(send, *args):
    mail.outbox.clear()
    send(*args)
    return mail.outbox[-1].body
