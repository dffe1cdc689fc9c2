"""The experiment's state machine (Experiment's transition methods), without processes: each transition
changes the state only from the states it allows, and only for the worker that holds the experiment;
a refused one returns False and changes nothing."""
import itertools

import pytest
from django.contrib.auth import get_user_model

from robotarium_portal.models import Experiment, Profile, Worker

STATES = [s for s, _ in Experiment.STATES]
_users = itertools.count()


def owner():
    n = next(_users)
    return get_user_model().objects.create_user(username="states%d@example.org" % n, email="states%d@example.org" % n)


def worker(kind="verify"):
    """A slot that holds experiments here; stopped, so that no watcher of another test finds it lost."""
    return Worker.objects.create(host="lab-pc", pid=1, kind=kind, domain=5, state=Worker.STOPPED)


def experiment_in(state, held_by=None):
    return Experiment.objects.create(owner=owner(), title="t", estimated_duration=10, number_of_robots=2,
                                     main_file="main.py", state=state, worker=held_by)


# (transition, the states it leaves from, the state it leads to); a worker-held transition gets the holder
TRANSITIONS = [
    ("submit", Experiment.EDITABLE, Experiment.SUBMITTED, lambda e, w: e.submit()),
    ("claim_verification", [Experiment.SUBMITTED], Experiment.VERIFYING, lambda e, w: e.claim_verification(w.pk)),
    ("queue", [Experiment.VERIFYING], Experiment.QUEUED, lambda e, w: e.queue(w.pk, {"verdict": "accepted"}, {})),
    ("reject", [Experiment.VERIFYING], Experiment.REJECTED, lambda e, w: e.reject(w.pk, "collisions", {}, {})),
    ("fail", [Experiment.VERIFYING, Experiment.RUNNING], Experiment.FAILED, lambda e, w: e.fail(w.pk, "broke")),
    ("complete", [Experiment.RUNNING], Experiment.COMPLETED, lambda e, w: e.complete(w.pk, "Run completed.")),
    ("cancel", Experiment.PENDING, Experiment.CANCELLED, lambda e, w: e.cancel("admin@example.org")),
    ("requeue", [Experiment.RUNNING, Experiment.VERIFYING], None, lambda e, w: e.requeue(w.pk, "The service stopped")),
]


@pytest.mark.parametrize("name, sources, target, go", TRANSITIONS, ids=[t[0] for t in TRANSITIONS])
def test_each_transition_goes_only_from_the_states_it_allows(name, sources, target, go):
    for state in STATES:
        holder = worker()
        experiment = experiment_in(state, held_by=holder)
        changed = go(experiment, holder)
        experiment.refresh_from_db()
        if state in sources:
            expected = target or (Experiment.QUEUED if state == Experiment.RUNNING else Experiment.SUBMITTED)
            assert changed and experiment.state == expected, (name, state)
        else:
            assert not changed and experiment.state == state, (name, state)


@pytest.mark.parametrize("name, go", [(t[0], t[3]) for t in TRANSITIONS if t[0] in ("queue", "reject", "fail",
                                                                                   "complete", "requeue")])
def test_an_outcome_is_written_only_by_the_worker_that_holds_the_experiment(name, go):
    holder, stranger = worker(), worker()
    for state in (Experiment.VERIFYING, Experiment.RUNNING):
        experiment = experiment_in(state, held_by=holder)
        assert not go(experiment, stranger)
        experiment.refresh_from_db()
        assert experiment.state == state and experiment.worker_id == holder.pk


def test_two_workers_claim_one_verification_and_one_run_only_one_wins():
    first, second = worker(), worker("runs")
    submitted = experiment_in(Experiment.SUBMITTED)
    assert submitted.claim_verification(first.pk)
    assert not Experiment.objects.get(pk=submitted.pk).claim_verification(second.pk)
    assert Experiment.objects.get(pk=submitted.pk).worker_id == first.pk
    Experiment.objects.filter(state=Experiment.QUEUED).update(state=Experiment.SAVED)   # other tests' queue
    older, newer = experiment_in(Experiment.SUBMITTED), experiment_in(Experiment.SUBMITTED)
    for e in (older, newer):   # queued in this order: first come, first served
        e.claim_verification(first.pk)
        e.queue(first.pk, {}, {})
    taken = [Experiment.claim_next_run(w.pk) for w in (second, first, second)]
    assert [e.pk if e else None for e in taken] == [older.pk, newer.pk, None]
    older.refresh_from_db()
    assert older.state == Experiment.RUNNING and older.attempts == 1 and older.worker_id == second.pk


def test_a_stop_mid_run_requeues_it_once_at_the_head_of_the_queue_with_the_run_named():
    holder = worker("runs")
    experiment = experiment_in(Experiment.QUEUED)
    Experiment.objects.filter(pk=experiment.pk).update(queued_at="2026-01-01T00:00:00Z")
    Experiment.objects.filter(state=Experiment.QUEUED).exclude(pk=experiment.pk).update(state=Experiment.SAVED)
    assert Experiment.claim_next_run(holder.pk).pk == experiment.pk
    experiment.refresh_from_db()
    assert experiment.requeue(holder.pk, "The service stopped")
    assert experiment.state == Experiment.QUEUED and experiment.worker is None
    assert experiment.detail.startswith("The service stopped during run 1 (at ")
    assert experiment.queued_at.year == 2026 and experiment.place_in_queue() == 1   # its place kept
    assert not experiment.requeue(holder.pk, "The service stopped")   # once


def test_a_requeue_at_a_restart_names_the_time_the_worker_stopped_not_the_restart():
    from datetime import datetime, timezone
    holder = worker("runs")
    experiment = experiment_in(Experiment.RUNNING, held_by=holder)
    stopped = datetime(2026, 11, 28, 9, 15, 30, tzinfo=timezone.utc)
    assert experiment.requeue(holder.pk, "The service stopped", stopped)
    assert "(at 2026-11-28 09:15:30 UTC)" in experiment.detail


def test_a_cancelled_run_keeps_what_its_job_recorded_and_stays_cancelled():
    holder = worker("runs")
    experiment = experiment_in(Experiment.RUNNING, held_by=holder)
    assert experiment.cancel("admin@example.org") and "Cancelled by an administrator" in experiment.detail
    assert not experiment.complete(holder.pk, "Run completed.", results="run-1/results/x")
    assert experiment.keep_results(results="run-1/results/x")
    experiment.refresh_from_db()
    assert experiment.state == Experiment.CANCELLED and experiment.results == "run-1/results/x"


def test_a_submission_clears_the_earlier_outcome():
    experiment = experiment_in(Experiment.FAILED)
    Experiment.objects.filter(pk=experiment.pk).update(detail="Failed: x", results="run-1/results/r",
                                                       run_outcome="script_error", verification={"verdict": "x"})
    experiment.refresh_from_db()
    assert experiment.submit()
    assert (experiment.detail, experiment.results, experiment.run_outcome, experiment.verification) == ("", "", "",
                                                                                                         None)
    assert experiment.submitted_at is not None


def test_an_account_is_approved_once():
    user, admin = owner(), owner()
    profile = Profile.objects.create(user=user, name="A", city="c", state="s", institute="i", reason="r",
                                     email_confirmed=True)
    assert profile.approve(admin) and profile.approved and profile.approved_by == admin
    assert not profile.approve(owner())
    profile.refresh_from_db()
    assert profile.approved_by == admin


def test_one_person_holds_one_verification_slot_at_a_time():
    first_slot, second_slot = worker(), worker()
    person = owner()
    mine = [Experiment.objects.create(owner=person, title="t", estimated_duration=10, number_of_robots=2,
                                      main_file="main.py", state=Experiment.SUBMITTED) for _ in range(2)]
    theirs = experiment_in(Experiment.SUBMITTED)
    assert mine[0].claim_verification(first_slot.pk)
    assert not mine[1].claim_verification(second_slot.pk)   # the same person's: it waits
    assert theirs.claim_verification(second_slot.pk)           # another person's goes first
    assert mine[0].queue(first_slot.pk, {}, {})
    assert mine[1].claim_verification(first_slot.pk)           # its turn once the first is done


def test_a_rejection_reads_rule_count_first_step_then_what_the_verifier_says():
    from robotarium_portal.jobs import rejection_text
    text = rejection_text({"rules": [
        {"rule": "collisions", "count": 168, "limit": 100, "first_step": 37, "message": "robots touched"},
        {"rule": "no_end", "count": None, "limit": None, "first_step": None,
         "message": "the script never called\n r.call_at_scripts_end()"},
        {"rule": "compile", "count": None, "limit": None, "first_step": None, "message": ""}]})
    assert text.splitlines() == ["collisions: 168 times, limit 100 (first at step 37). robots touched",
                                 "no_end: the script never called r.call_at_scripts_end()", "compile:"]
