"""A run of a script as one typed record: how it ended, its steps and counts, its experiments, what of
it was not saved. `./robotarium run` (verify, demo, the portal's jobs) keeps it as run.json in the
run's folder, and this module alone reads and writes that file (read, write, write_atomically), so
the CLI, `report`, the results page and the portal all see the same fields. The file keeps its
shape: the last experiment's fields at the top, every experiment under "runs".

Experiment is what one Robotarium's testbed said when its experiment ended (or what was known of
it: a lost testbed); RunRecord is the run around it. Plain Python: no ROS, no numpy.
"""
import dataclasses
import json
import os
from typing import Any

FILE = "run.json"


@dataclasses.dataclass
class Experiment:
    """One experiment of a run, as its testbed ended it (robotarium_client.Robotarium.run_info)."""
    run_id: str = ""
    recording: str = ""                   # the bag's folder, "" when not recorded
    report: str = ""                      # the debug report the testbed made
    outcome: str = ""                     # robotarium_core.outcomes.NAMES
    detail: str = ""
    ended: bool = False                   # the testbed confirmed its end
    steps: int = 0                        # the testbed's steps, as the report counts them
    collisions: int = 0
    boundary_violations: int = 0
    actuator_limit_iterations: int = 0
    command_timeouts: int = 0
    real_time: bool = True
    number_of_robots: int | None = None
    end_reason: str = ""
    dropped: dict = dataclasses.field(default_factory=dict)   # {input: {reason: count}}
    recording_stopped_at_step: int | None = None
    recording_stopped_because: str | None = None
    stale_pose_stops: int = 0
    hardware: bool = False
    hardware_seed: int = 0
    audit: bool = False                   # a verification run
    first_collision_step: int | None = None
    first_boundary_step: int | None = None
    safety_interventions: int = 0
    ideal_interventions: int = 0          # of those, what a verification's certificate would have changed
    ended_by_unsent_request_at_step: int | None = None
    time_limit: dict | None = None        # {"limit", "step", "sim_time", "note"} where the time limit ended it
    # the safety node restarted mid-run, armed again by the testbed, the run going on (restarts.went_on's words)
    safety_restarts: list = dataclasses.field(default_factory=list)
    api: str = ""                         # the script's Robotarium API: "guide" (rps 0.0.0) or "2" (the 2.x
                                          # simulator's); "" in a file from before it was kept

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> "Experiment":
        return cls(**_known(cls, values))


# What a RunRecord takes from its last experiment (the file's top level shows them).
_FROM_EXPERIMENT = tuple(f.name for f in dataclasses.fields(Experiment) if f.name not in ("report", "outcome", "detail"))


@dataclasses.dataclass
class RunRecord(Experiment):
    """A run: how the script's run ended (outcome, detail, exit code), its last experiment's fields,
    all its experiments, and what the command added (script, start, wall time, data left out, the
    Robotarium's verdict where the safety layer changed commands)."""
    exit_code: int = 0
    step_calls: int | None = None          # the script's step() calls (lockstep: = steps)
    experiments: list[Experiment] = dataclasses.field(default_factory=list)
    script: str = ""
    started: str = ""                      # "%Y-%m-%d %H:%M:%S"
    wall_time: float = 0.0                 # s, the script's process
    data_not_saved: dict = dataclasses.field(default_factory=dict)   # {file: why}
    recording_lost_poses: int = 0          # poses of this many steps missing from the bag
    recording_first_lost_step: int | None = None
    verdict: dict | None = None            # verification's document (its "text" too) where run judged the script
    timings: dict = dataclasses.field(default_factory=dict)

    @property
    def last(self) -> Experiment | None:
        return self.experiments[-1] if self.experiments else None

    def take_last_experiment(self) -> None:
        """Copy the last experiment's fields to the top (how the file has always shown a run)."""
        if self.last is not None:
            for name in _FROM_EXPERIMENT:
                setattr(self, name, getattr(self.last, name))

    def to_dict(self) -> dict[str, Any]:
        values = dataclasses.asdict(self)
        values["runs"] = values.pop("experiments")
        return values

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> "RunRecord":
        record = cls(**_known(cls, {k: v for k, v in values.items() if k != "experiments"}))
        record.experiments = [Experiment.from_dict(e) for e in values.get("runs") or values.get("experiments") or []
                              if isinstance(e, dict)]
        return record


def _known(cls, values):
    """The entries of `values` that are fields of `cls` (older and newer files alike)."""
    names = {f.name for f in dataclasses.fields(cls)}
    return {k: v for k, v in (values or {}).items() if k in names}


def read(folder_or_file: str) -> RunRecord | None:
    """The run kept in a run folder (or a run.json path); None where there is none or it is unreadable."""
    path = folder_or_file if folder_or_file.endswith(".json") else os.path.join(folder_or_file, FILE)
    try:
        with open(path, encoding="utf-8") as f:
            values = json.load(f)
    except (OSError, ValueError):
        return None
    return RunRecord.from_dict(values) if isinstance(values, dict) else None


def write(record: RunRecord, folder_or_file: str) -> str:
    """Keep `record` as run.json (in a folder, or at a path ending in .json), atomically: a reader sees
    the old file or the new one. Returns the path."""
    path = folder_or_file if folder_or_file.endswith(".json") else os.path.join(folder_or_file, FILE)
    scratch = "%s.%d.tmp" % (path, os.getpid())   # a writer's own: two writers never take each other's
    with open(scratch, "w", encoding="utf-8") as f:
        json.dump(record.to_dict(), f, indent=2)
    os.replace(scratch, path)
    return path
