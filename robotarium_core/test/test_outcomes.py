"""How a run ended: the plain module's numbers are the messages' constants, and its words."""
from robotarium_core import model, outcomes
from robotarium_msgs.msg import TestbedStatus


def test_outcome_numbers_are_the_message_constants():
    for name, value in vars(outcomes).items():
        if name.isupper() and isinstance(value, int) and hasattr(TestbedStatus, "OUTCOME_" + name):
            assert getattr(TestbedStatus, "OUTCOME_" + name) == value, name
    constants = {n[len("OUTCOME_"):] for n in dir(TestbedStatus) if n.startswith("OUTCOME_")}
    assert constants <= {n for n in vars(outcomes) if n.isupper()}
    assert outcomes.UNFINISHED not in {getattr(TestbedStatus, "OUTCOME_" + n) for n in constants}


def test_first_lines_and_exit_codes():
    assert outcomes.first_line(outcomes.COMPLETED) == "Run completed."
    line = outcomes.first_line(outcomes.SCRIPT_ERROR, "the script raised KeyError: 'goal' at step 3")
    assert line == "Run did not complete: the script raised KeyError: 'goal' at step 3."
    assert outcomes.first_line(outcomes.UNFINISHED).startswith("Run did not complete: the recording ends")
    note = "Stopped at the time limit: 1 s of testbed time (step 31, 1.02 s); the rest of the script did not run."
    assert outcomes.first_line(outcomes.TIME_LIMIT, note) == note
    assert outcomes.of_request(outcomes.NONE) == outcomes.COMPLETED
    assert outcomes.EXIT_CODES[outcomes.COMPLETED] == 0
    failures = [code for outcome, code in outcomes.EXIT_CODES.items() if outcome != outcomes.COMPLETED]
    assert 0 not in failures and all(0 < code < 256 and code not in (247, 254) for code in failures)
    assert len({outcomes.EXIT_CODES[o] for o in (outcomes.SCRIPT_ERROR, outcomes.TESTBED_LOST,
                                                   outcomes.INTERRUPTED, outcomes.NO_END)}) == 4


def test_an_incomplete_run_never_gets_the_acceptance_estimate():
    assert "Acceptance of your experiment is likely" in model.debug_report(100, 0, 0, 0)
    text = model.debug_report(100, 0, 0, 0, completed=False)
    assert "Acceptance" not in text and model.NOT_COMPLETED in text
    text = model.debug_report(100, 3, 0, 0, completed=False)
    assert "3 iteration(s) robots were outside" in text and model.NOT_COMPLETED in text
