"""The dashboard, the queue, Create Experiment, an experiment's page and results, and their files."""
import functools
import json
import os
import re
import shutil
import time

from django.conf import settings
from django.contrib import messages
from django.contrib.auth.decorators import login_required
from django.db import close_old_connections, transaction
from django.http import Http404, HttpResponse, StreamingHttpResponse
from django.shortcuts import redirect, render
from django.urls import reverse
from django.utils import timezone
from django.views.decorators.http import require_POST

from robotarium_core.config import TestbedConfig
from robotarium_portal import files, jobs
from robotarium_portal.forms import ExperimentForm
from robotarium_portal.models import Experiment, ExperimentFile, ReturnMessage, Worker

LIVE_RATE = 20            # events a second at most from a live stream (the testbed's 30 Hz poses, thinned)
LIVE_STATE_PERIOD = 1.0   # s between two looks at the experiment's state for a live stream
LIVE_STREAM = 60          # s a live stream lasts before the browser opens the next (a server thread each)
UNMEASURED_START = 30   # s a run takes beyond its declared duration, for the wait before any run was measured


def visible_experiment(request, pk):
    """The experiment, for its owner or an administrator; for anybody else it does not exist (404)."""
    experiment = Experiment.objects.filter(pk=pk).select_related("owner").first()
    if experiment is None or (experiment.owner_id != request.user.pk and not request.user.is_staff):
        raise Http404("no such experiment")
    return experiment


@functools.cache
def testbed_config():
    """The testbed configuration (the arena, the robots' size), read once."""
    return TestbedConfig.load()


def queue_summary():
    """Total experiments in the queue (running included) and an honest wait for one submitted now: each run
    ahead takes what the last runs measured (their ./robotarium run, start to results), or, before any was
    measured, its declared duration and a start; shared by the run slots that are alive."""
    ahead = list(Experiment.objects.filter(state__in=(Experiment.QUEUED, Experiment.RUNNING)))
    measured = [t for t in Experiment.objects.filter(state__in=(Experiment.COMPLETED, Experiment.FAILED))
                .exclude(timings={}).order_by("-finished_at").values_list("timings__run_command", flat=True)[:20]
                if isinstance(t, (int, float))]
    typical = sum(measured) / len(measured) if measured else None
    now = timezone.now()
    total = 0.0
    for e in ahead:
        each = typical if typical is not None else min(e.estimated_duration, jobs.time_limit()) + UNMEASURED_START
        if e.state == Experiment.RUNNING and e.started_at:
            each = max(0.0, each - (now - e.started_at).total_seconds())
        total += each
    slots = max(1, Worker.objects.filter(state=Worker.ALIVE, kind=Worker.RUNS).count())
    wait = total / slots
    source = ("from the last %s (%s each on average)" % ("run" if len(measured) == 1 else "%d runs" % len(measured),
                                                         _duration(typical)) if measured
              else "from the declared durations (no run measured yet)")
    text = ("An experiment submitted now starts at once after its verification." if not ahead else
            "An experiment submitted now starts in about %s, %s." % (_duration(wait), source))
    return {"in_queue": len(ahead), "wait_seconds": round(wait), "estimate": text}


def _duration(seconds):
    if seconds < 90:
        return "%d s" % round(seconds)
    return "%d minutes" % round(seconds / 60)


@login_required
def dashboard(request):
    """The guide's tabs: Pending = submitted and not finished (with its state and place), Completed =
    finished (with its outcome), and the drafts (saved, never submitted) apart."""
    mine = Experiment.objects.filter(owner=request.user)
    pending = list(mine.filter(state__in=Experiment.PENDING).order_by("submitted_at", "pk"))
    completed = list(mine.filter(state__in=Experiment.DONE).order_by("-finished_at", "-pk"))
    for e in pending:
        e.place, e.step = e.place_in_queue(), running_step(e)
    for e in completed:
        e.outcome = outcome_line(e)
    tab = request.GET.get("tab") if request.GET.get("tab") in ("completed", "drafts") else "pending"
    return render(request, "portal/dashboard.html", {
        "tab": tab, "pending": pending, "completed": completed, "drafts": mine.filter(state=Experiment.SAVED),
        **queue_summary()})


def outcome_line(experiment):
    """A finished experiment's outcome in a few words (its first line of detail)."""
    first = shown_text(experiment.detail).strip().splitlines()
    if experiment.state == Experiment.REJECTED:
        return first[1] if len(first) > 1 else "rejected by the verification"
    return first[0] if first else experiment.state


def running_step(experiment):
    return jobs.current_step(experiment) if experiment.state == Experiment.RUNNING else None


def shown_text(text):
    """A job's text as a person may read it: the service's own folders (the job's box, the data folder)
    never shown, a file of the experiment named by its name. None stays None."""
    if text is None:
        return None
    boxes = re.escape(str(settings.JOB_BOXES_DIR).rstrip("/"))
    text = re.sub(boxes + r"/[^\s/'\"]+/(?:work/)?", "", text)
    return text.replace(str(settings.DATA_DIR), "(the service's folder)")


@login_required
def queue(request):
    rows = Experiment.objects.filter(state__in=(Experiment.QUEUED, Experiment.RUNNING)).order_by("queued_at", "pk")
    return render(request, "portal/queue.html", {"rows": rows, **queue_summary()})


def save_experiment(form, user):
    """The valid form's fields and files into its experiment (files only inside its own folder)."""
    data = form.cleaned_data
    with transaction.atomic():
        experiment = form.save(commit=False)
        if experiment.owner_id is None:
            experiment.owner = user
        experiment.main_file = data["main_file"]
        experiment.save()
        for name in data.get("remove") or []:
            os.remove(files.inside(experiment.files_dir, name))
            ExperimentFile.objects.filter(experiment=experiment, name=name).delete()
        for upload in data.get("upload") or []:
            files.save_upload(experiment.files_dir, upload)
            ExperimentFile.objects.update_or_create(experiment=experiment, name=upload.name,
                                                    defaults={"size": upload.size})
    return experiment


def submit(user, experiment):
    """Submit, unless the account may not or has too many pending (then why, in words); its verification job in
    the same transaction (the queue is a table of the same database): submitted and its job, or neither. (Put
    on the queue after the commit, a database lost in between left it submitted with no job, for ever.) The
    pages and the API both submit through here."""
    profile = getattr(user, "profile", None)
    if profile is None or not profile.email_confirmed:
        return "Confirm your email address first (the link in the mail you got; Resend it from the log-in page)."
    if not profile.approved:
        return "Your account waits for an administrator's approval; you can save experiments meanwhile."
    if not experiment.main_file:
        return "Choose the main file (the script that is run)."
    with transaction.atomic():
        pending = Experiment.objects.filter(owner=user, state__in=Experiment.PENDING).count()
        if pending >= settings.PORTAL_MAX_PENDING:
            return ("You have %d experiments pending, the most one may have; submit this one when one of them "
                    "has finished (it is saved)." % pending)
        if not experiment.submit():
            return "It is %s already." % experiment.state
        jobs.enqueue_verification(experiment)
    return None


def _edit(request, experiment):
    form = ExperimentForm(request.POST or None, request.FILES or None, instance=experiment)
    if request.method == "POST" and form.is_valid():
        experiment = save_experiment(form, request.user)
        if request.POST.get("action") == "submit":
            problem = submit(request.user, experiment)
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
        "step": running_step(experiment), "detail": shown_text(experiment.detail),
        "live": experiment.state in Experiment.PENDING, "live_url": reverse("live", args=[experiment.pk]),
        "arena_json": json.dumps(list(testbed_config().arena)), "robot_radius": testbed_config().robot_diameter / 2,
        "differs": experiment.differs_from_verification(),
        "place": experiment.place_in_queue(),
        "return_messages": experiment.return_messages.all(),
        "results": results_dir is not None,
        "video": next((n for n in ("run.mp4", "run.gif") if n in names), None),
        "plot": "trajectories.png" if "trajectories.png" in names else None,
        "report": shown_text(_read(results_dir, "report.txt")), "log": shown_text(_read(results_dir, "log.txt")),
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
    return files.download(request, files.result_path(experiment.results_dir, name),
                          as_attachment="download" in request.GET)


def result_listing(experiment):
    """[(name, size)] of the results folder's files and its data/ files ('data/NAME'); [] before results."""
    folder = experiment.results_dir
    return (files.listing(folder) + files.listing(folder, "data")) if folder else []


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


def bad_request(request, exception=None):
    """Django's 400 (a request past its limits: too many files or fields at once), said in words."""
    return render(request, "portal/bad_request.html", {"max_files": settings.PORTAL_MAX_FILES,
                                                       "max_bytes": settings.PORTAL_MAX_FILE_BYTES}, status=400)


@login_required
def live(request, pk):
    """The experiment's page, live (server-sent events, no plug-in): its state as it changes and, while it
    runs, the newest poses and drawing from its testbed (jobs.live_file) as they come, at most
    LIVE_RATE a second. A stream lasts LIVE_STREAM s; the browser's EventSource then opens the next."""
    experiment = visible_experiment(request, pk)
    response = StreamingHttpResponse(_live_events(experiment), content_type="text/event-stream")
    response["Cache-Control"] = "no-cache"
    response["X-Accel-Buffering"] = "no"   # a proxy in front passes each event on at once
    return response


def _event(name, data):
    return ("event: %s\ndata: %s\n\n" % (name, json.dumps(data))).encode()


def _live_events(experiment):
    yield b"retry: 1000\n\n"
    last_state, tail, offset, ends = None, b"", None, time.monotonic() + LIVE_STREAM
    looked = 0.0
    while time.monotonic() < ends:
        if time.monotonic() - looked >= LIVE_STATE_PERIOD:   # the state: from the database, once a second
            looked = time.monotonic()
            experiment.refresh_from_db()
            close_old_connections()
            state = {"state": experiment.state, "place": experiment.place_in_queue(),
                     "step": running_step(experiment)}
            if state != last_state:
                yield _event("state", state)
                last_state = state
            if experiment.state in Experiment.DONE or experiment.state == Experiment.SAVED:
                return
        if experiment.state == Experiment.RUNNING:
            poses, drawing, offset, tail = _new_lines(jobs.live_file(experiment), offset, tail)
            if drawing:
                yield _event("drawing", drawing)
            if poses:
                yield _event("poses", poses)
        time.sleep(1.0 / LIVE_RATE)


def _new_lines(path, offset, tail):
    """(newest poses, newest drawing, new offset, an unfinished line) of what the feed appended since
    offset; a first look starts at the newest drawing and poses already there."""
    try:
        with open(path, "rb") as f:
            size = f.seek(0, os.SEEK_END)
            if offset is None or offset > size:
                offset = 0
            f.seek(offset)
            chunk = tail + f.read(size - offset)
    except OSError:
        return None, None, offset, tail
    *lines, tail = chunk.split(b"\n")
    poses = drawing = None
    for line in reversed(lines):
        if poses is None and line.startswith(b'{"t"') and b'"step"' in line:
            poses = json.loads(line)
        elif drawing is None and b'"drawing"' in line:
            drawing = json.loads(line)
        if poses is not None and drawing is not None:
            break
    return poses, drawing, size, tail
