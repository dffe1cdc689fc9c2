"""The JSON API (`./robotarium submit`, docs/portal.md#the-json-api): the pages' rules, answered as JSON.

A request carries a person's API token (`Authorization: Bearer rbt_...`, made on the account page or by
`./robotarium serve --create-token EMAIL`); it acts as that person: the same experiments, the same
checks before a submission, the same 404 for anything not theirs. Tokens only (no session cookie), so
no cross-site form can post here; the pages' own forms keep Django's CSRF protection.

    GET  /api/experiments/                  the person's experiments
    POST /api/experiments/                  create and submit (multipart: the form's fields and files)
    GET  /api/experiments/<id>/             its state, place, step, detail, verdict, results' files
    GET  /api/experiments/<id>/results/<f>  one file of its results (as the results page serves it)
"""
import functools

from django.http import Http404, JsonResponse
from django.views.decorators.csrf import csrf_exempt
from django.views.decorators.http import require_GET

from robotarium_portal import views_experiments as pages
from robotarium_portal.forms import ExperimentForm
from robotarium_portal.models import ApiToken, Experiment


def with_token(view):
    """The token's person as request.user, or 401; a page's Http404 as a JSON 404."""
    @csrf_exempt
    @functools.wraps(view)
    def wrapped(request, *args, **kwargs):
        scheme, _, key = request.headers.get("Authorization", "").partition(" ")
        user = ApiToken.user_of(key.strip()) if scheme.lower() == "bearer" else None
        if user is None:
            return JsonResponse({"error": "no valid API token: send 'Authorization: Bearer TOKEN' (make one on "
                                          "your account page)"}, status=401)
        request.user = user
        try:
            return view(request, *args, **kwargs)
        except Http404:
            return JsonResponse({"error": "no such experiment"}, status=404)
    return wrapped


def summary(experiment):
    """What the API says of an experiment (and `submit` prints)."""
    results = pages.result_listing(experiment)
    return {
        "id": experiment.pk, "title": experiment.title, "state": experiment.state,
        "main_file": experiment.main_file, "number_of_robots": experiment.number_of_robots,
        "estimated_duration": experiment.estimated_duration, "detail": pages.shown_text(experiment.detail),
        "place_in_queue": experiment.place_in_queue(), "step": pages.running_step(experiment),
        "rules": [r for r in (experiment.verification or {}).get("rules") or []],
        "run_outcome": experiment.run_outcome, "verify_seconds": (experiment.timings or {}).get("verify_command"),
        "results_folder": results and experiment.results.rsplit("/", 1)[-1],
        "results": [{"name": name, "size": size, "url": "/api/experiments/%d/results/%s" % (experiment.pk, name)}
                    for name, size in results],
        "page": "/experiments/%d/" % experiment.pk,
    }


@with_token
def experiments(request):
    if request.method == "GET":
        return JsonResponse({"experiments": [summary(e) for e in Experiment.objects.filter(owner=request.user)]})
    if request.method != "POST":
        return JsonResponse({"error": "GET or POST"}, status=405)
    form = ExperimentForm(request.POST, request.FILES, instance=Experiment(owner=request.user))
    if not form.is_valid():
        return JsonResponse({"error": "not created", "fields": {k: [str(m) for m in v] for k, v in form.errors.items()}},
                            status=400)
    experiment = pages.save_experiment(form, request.user)
    problem = pages.submit(request.user, experiment)
    if problem:
        return JsonResponse(dict(summary(experiment), error="saved, not submitted: " + problem), status=409)
    return JsonResponse(summary(experiment), status=201)


@with_token
@require_GET
def experiment(request, pk):
    return JsonResponse(summary(pages.visible_experiment(request, pk)))


@with_token
@require_GET
def result_file(request, pk, name):
    return pages.result_file.__wrapped__(request, pk, name)
