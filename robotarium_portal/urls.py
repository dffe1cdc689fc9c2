from django.contrib import admin
from django.contrib.auth import views as auth_views
from django.contrib.staticfiles.views import serve as static_file
from django.urls import path, re_path

from robotarium_portal import api
from robotarium_portal import views_accounts as accounts
from robotarium_portal import views_experiments as experiments

urlpatterns = [
    path("", experiments.dashboard, name="dashboard"),
    path("queue/", experiments.queue, name="queue"),
    path("experiments/new/", experiments.create, name="create"),
    path("experiments/<int:pk>/", experiments.experiment_page, name="experiment"),
    path("experiments/<int:pk>/settings.json", experiments.settings_json, name="settings_json"),
    path("experiments/<int:pk>/files/<str:name>", experiments.script_file, name="script_file"),
    path("experiments/<int:pk>/results/<path:name>", experiments.result_file, name="result_file"),
    path("experiments/<int:pk>/message/", experiments.return_message, name="return_message"),
    path("experiments/<int:pk>/delete/", experiments.delete, name="delete"),
    path("experiments/<int:pk>/live/", experiments.live, name="live"),
    path("api/experiments/", api.experiments, name="api_experiments"),
    path("api/experiments/<int:pk>/", api.experiment, name="api_experiment"),
    path("api/experiments/<int:pk>/results/<path:name>", api.result_file, name="api_result_file"),
    path("signup/", accounts.signup, name="signup"),
    path("confirm/resend/", accounts.resend, name="resend"),
    path("confirm/<str:uidb64>/<str:token>/", accounts.confirm, name="confirm"),
    path("staff/approvals/", accounts.approvals, name="approvals"),
    path("staff/approvals/<int:pk>/", accounts.approve, name="approve"),
    path("account/", accounts.account, name="account"),
    path("login/", auth_views.LoginView.as_view(authentication_form=accounts.EmailLoginForm), name="login"),
    path("logout/", auth_views.LogoutView.as_view(), name="logout"),
    path("password/reset/", accounts.PasswordResetView.as_view(), name="password_reset"),
    path("password/reset/sent/", auth_views.PasswordResetDoneView.as_view(), name="password_reset_done"),
    path("password/reset/<uidb64>/<token>/", auth_views.PasswordResetConfirmView.as_view(),
         name="password_reset_confirm"),
    path("password/reset/done/", auth_views.PasswordResetCompleteView.as_view(), name="password_reset_complete"),
    path("admin/", admin.site.urls),
    # The admin pages' CSS and scripts (the portal's own style is inline): Django's file view, fine for a
    # class's service behind one WSGI server; a large installation puts a web server in front.
    re_path(r"^static/(?P<path>.*)$", static_file, {"insecure": True}),
]

handler400 = "robotarium_portal.views_experiments.bad_request"
