"""The whole suite's order for pytest-xdist's work stealing (tests/conftest.py), plain Python.

`--dist worksteal` first cuts the collected tests into one contiguous share per worker (each takes
len(pending) // workers left), then an idle worker takes the back half of the longest queue. With the
longest modules simply put first, they all fell into the first share: one worker ran the soak, the
service, the safe scripts and the fleets one after another while the others, done with the short
tests, stole only what stood behind them (2026-11-29: the fleet tests ran alone for the last 3
minutes of a 19.5-minute suite). Here each share gets its fair part of the long modules, at its front
(begun first, the short ones fill in around them; stolen, the short ones go), every module's tests
kept together where it fits (module fixtures start a testbed, a database, a service once).
"""


def share_sizes(count, workers):
    """How many tests worksteal's first schedule hands each of `workers` idle workers, in order."""
    sizes = []
    for k in range(workers):
        sizes.append(count // (workers - k))
        count -= sizes[-1]
    return sizes


def order(modules, workers):
    """The tests in the order to collect them. modules: [(items, seconds)] in collection order, seconds
    each module's estimated worker time. The longest go first (longest processing time first), each to
    the share with the least time so far that has room for the whole module; a module with no such room
    fills the shares that have some, in turn. Each share: its modules longest first."""
    sizes = share_sizes(sum(len(items) for items, _ in modules), workers)
    shares = [{"room": size, "seconds": 0.0, "parts": []} for size in sizes]
    for items, seconds in sorted(modules, key=lambda module: -module[1]):   # (stable: equal ones keep their order)
        fits = [share for share in shares if share["room"] >= len(items)]
        if fits:
            parts = [(min(fits, key=lambda share: share["seconds"]), items)]
        else:
            parts, rest = [], list(items)
            for share in sorted(shares, key=lambda share: share["seconds"]):
                if rest and share["room"]:
                    parts.append((share, rest[:share["room"]]))
                    rest = rest[share["room"]:]
        for share, part in parts:
            share["room"] -= len(part)
            share["seconds"] += seconds * len(part) / len(items)
            share["parts"].append((seconds, part))
    return [item for share in shares
            for _, part in sorted(share["parts"], key=lambda p: -p[0]) for item in part]
