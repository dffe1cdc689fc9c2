"""Run a module under cProfile timed by this thread's CPU time (time.thread_time), not the wall
clock: on a loaded machine a wall-clock profile charges a function for the time its process waited
for a core. Writes the stats to OUTPUT on SIGINT/SIGTERM or exit.
Run: python devtools/cpu_profile.py OUTPUT -m MODULE [ARGS...]
"""
import cProfile
import runpy
import sys
import time

USAGE = "usage: python devtools/cpu_profile.py OUTPUT -m MODULE [ARGS...]"


def main():
    if sys.argv[1:2] in (["-h"], ["--help"]):
        print(USAGE + "\n\n" + __doc__.split("Run:")[0].strip())
        return
    if len(sys.argv) < 4 or sys.argv[2] != "-m":
        sys.exit(USAGE)
    output, _, module, *rest = sys.argv[1:]
    sys.argv = [module] + rest
    profile = cProfile.Profile(time.thread_time)
    profile.enable()
    try:
        runpy.run_module(module, run_name="__main__", alter_sys=True)
    except (KeyboardInterrupt, SystemExit):
        pass
    finally:
        profile.disable()
        profile.dump_stats(output)


if __name__ == "__main__":
    main()
