"""The dashboard, the queue, Create Experiment, an experiment's page and results, and their files."""
import json
import os
import shutil

from django.conf import settings
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.db import transaction
from django.http import Http404, HttpResponse
from django.shortcuts import redirect, render
from django.views.decorators.http import require_POST

from robotarium_portal import files, jobs
from robotarium_portal.forms import ExperimentForm
from robotarium_portal.models import Experiment, ExperimentFile, ReturnMessage


def visible_experiment(request, pk):
    """The experiment, for its owner or an administrator; for anybody else it does not exist (404)."""
    experiment = Experiment.objects.filter(pk=pk).select_related("owner").first()
    if experiment is None or (experiment.owner_id != request.user.pk and not request.user.is_staff):
        raise Http404("no such experiment")
    return experiment


def queue_summary():
    """Total experiments in the queue (running included) and the wait for a new one: each may take up to
    the time limit (15 minutes), first come, first served."""
    waiting = Experiment.objects.filter(state__in=(Experiment.QUEUED, Experiment.RUNNING)).count()
    return {"in_queue": waiting, "wait_minutes": round(waiting * jobs.time_limit() / 60)}


@login_required
def dashboard(request):
    mine = Experiment.objects.filter(owner=request.user)
    return render(request, "portal/dashboard.html", {
        "tab": "completed" if request.GET.get("tab") == "completed" else "pending",
        "pending": mine.exclude(state__in=Experiment.DONE),
        "completed": mine.filter(state__in=Experiment.DONE),
        **queue_summary()})


@login_required
def queue(request):
    rows = Experiment.objects.filter(state__in=(Experiment.QUEUED, Experiment.RUNNING)).order_by("queued_at", "pk")
    return render(request, "portal/queue.html", {"rows": rows, **queue_summary()})


def _save_form(request, form, experiment):
    """The form's fields and files into the experiment (files only inside its own folder)."""
    data = form.cleaned_data
    experiment.main_file = data["main_file"]
    experiment.save()
    for name in data.get("remove") or []:
        os.remove(files.inside(experiment.files_dir, name))
        ExperimentFile.objects.filter(experiment=experiment, name=name).delete()
    for upload in data.get("upload") or []:
        files.save_upload(experiment.files_dir, upload)
        ExperimentFile.objects.update_or_create(experiment=experiment, name=upload.name,
                                                defaults={"size": upload.size})


def _submit(request, experiment):
    """Submit, unless the account may not or has too many pending; the verification job after the commit."""
    profile = getattr(request.user, "profile", None)
    if profile is None or not profile.email_confirmed:
        return "Confirm your email address first (the link in the mail you got; Resend it from the log-in page)."
    if not profile.approved:
        return "Your account waits for an administrator's approval; you can save experiments meanwhile."
    if not experiment.main_file:
        return "Choose the main file (the script that is run)."
    with transaction.atomic():
        pending = Experiment.objects.filter(owner=request.user, state__in=Experiment.PENDING).count()
        if pending >= settings.PORTAL_MAX_PENDING:
            return ("You have %d experiments pending, the most one may have; submit this one when one of them "
                    "has finished (it is saved)." % pending)
        if not experiment.submit():
            return "It is %s already." % experiment.state
        transaction.on_commit(lambda: jobs.enqueue_verification(experiment))
    return None


def _edit(request, experiment):
    form = ExperimentForm(request.POST or None, request.FILES or None, instance=experiment)
    if request.method == "POST" and form.is_valid():
        with transaction.atomic():
            experiment = form.save(commit=False)
            if experiment.owner_id is None:
                experiment.owner = request.user
            _save_form(request, form, experiment)
        if request.POST.get("action") == "submit":
            problem = _submit(request, experiment)
            if problem:
                messages.error(request, "Not submitted: " + problem)
            else:
                messages.success(request, "Submitted: it is verified now, then queued.")
        else:
            messages.success(request, "Saved.")
        return redirect("experiment", pk=experiment.pk)
    return form


@login_required
def create(request):
    result = _edit(request, Experiment(owner=request.user, estimated_duration=60, number_of_robots=1))
    if not isinstance(result, ExperimentForm):
        return result
    return render(request, "portal/experiment_form.html", {"form": result, "experiment": None})


@login_required
def experiment_page(request, pk):
    experiment = visible_experiment(request, pk)
    form = None
    if experiment.state in Experiment.EDITABLE and experiment.owner_id == request.user.pk:
        result = _edit(request, experiment)
        if not isinstance(result, ExperimentForm):
            return result
        form = result
    elif request.method == "POST":
        messages.error(request, "This experiment cannot be changed while it is %s." % experiment.state)
        return redirect("experiment", pk=pk)
    results_dir = experiment.results_dir
    listing = files.listing(results_dir) if results_dir else []
    names = {name for name, _ in listing}
    context = {
        "experiment": experiment, "form": form, "scripts": experiment.files.all(),
        "step": jobs.current_step(experiment) if experiment.state == Experiment.RUNNING else None,
        "differs": experiment.differs_from_verification(),
        "place": experiment.place_in_queue(), "slot_minutes": round(jobs.time_limit() / 60),
        "return_messages": experiment.return_messages.all(),
        "results": results_dir is not None,
        "video": next((n for n in ("run.mp4", "run.gif") if n in names), None),
        "plot": "trajectories.png" if "trajectories.png" in names else None,
        "report": _read(results_dir, "report.txt"), "log": _read(results_dir, "log.txt"),
        "data_files": files.listing(results_dir, "data") if results_dir else [],
        "log_files": [(n, s) for n, s in listing if n in ("log.txt", "report.txt", "run.json")],
        "recording": [(n, s) for n, s in listing if n.endswith(".mcap") or n == "metadata.yaml"],
        **queue_summary(),
    }
    return render(request, "portal/experiment.html", context)


def _read(folder, name, limit=200_000):
    if folder is None:
        return None
    try:
        with open(os.path.join(folder, name), encoding="utf-8", errors="replace") as f:
            return f.read(limit)
    except OSError:
        return None


@login_required
def settings_json(request, pk):
    experiment = visible_experiment(request, pk)
    response = HttpResponse(json.dumps(experiment.settings_dict(), indent=2), content_type="application/json")
    response["Content-Disposition"] = 'attachment; filename="experiment-%d-settings.json"' % experiment.pk
    return response


@login_required
def script_file(request, pk, name):
    experiment = visible_experiment(request, pk)
    if not experiment.files.filter(name=name).exists():
        raise Http404("no such file")
    return files.download(request, files.inside(experiment.files_dir, name), as_attachment="download" in request.GET)


@login_required
def result_file(request, pk, name):
    experiment = visible_experiment(request, pk)
    if experiment.results_dir is None:
        raise Http404("no results")
    return files.download(request, files.inside(experiment.results_dir, name), as_attachment="download" in request.GET)


@login_required
@require_POST
def return_message(request, pk):
    if not request.user.is_staff:
        raise Http404("no such page")
    experiment = visible_experiment(request, pk)
    text = request.POST.get("text", "").strip()
    if text:
        ReturnMessage.objects.create(experiment=experiment, author=request.user, text=text[:5000])
        messages.success(request, "Return message added.")
    return redirect("experiment", pk=pk)


@login_required
@require_POST
def delete(request, pk):
    experiment = visible_experiment(request, pk)
    if experiment.owner_id != request.user.pk or experiment.state in Experiment.PENDING:
        messages.error(request, "Only its owner may delete an experiment, and not while it is %s." % experiment.state)
        return redirect("experiment", pk=pk)
    shutil.rmtree(experiment.folder, ignore_errors=True)
    experiment.delete()
    messages.success(request, "Deleted.")
    return redirect("dashboard")
