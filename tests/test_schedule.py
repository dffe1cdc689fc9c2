"""The suite's order for pytest-xdist's work stealing (devtools.schedule): each worker's first share
begins with its fair part of the long modules."""
from devtools.schedule import order, share_sizes


def test_shares_are_cut_as_worksteal_cuts_them():
    assert share_sizes(10, 3) == [3, 3, 4]   # 10 // 3, then 7 // 2, then the rest
    assert share_sizes(820, 3) == [273, 273, 274]
    assert share_sizes(5, 1) == [5]


def test_each_share_begins_with_a_long_module_and_nothing_is_lost_or_doubled():
    a, b, c = (["%s%d" % (name, k) for k in range(5)] for name in "abc")
    short = ["u%d" % k for k in range(30)]
    ordered = order([(short, 3.0), (a, 100.0), (b, 90.0), (c, 80.0)], 3)
    assert sorted(ordered) == sorted(a + b + c + short)
    assert [ordered[0:5], ordered[15:20], ordered[30:35]] == [a, b, c]   # all three long ones begin at once


def test_a_share_takes_the_next_long_module_where_it_has_the_least_time():
    modules = [(["a"], 100.0), (["b"], 60.0), (["c"], 50.0), (["d", "e", "f"], 0.3)]
    ordered = order(modules, 2)    # shares of 3: a | b, c (b and c together are about a's time)
    assert ordered[0] == "a" and ordered[3:5] == ["b", "c"]


def test_one_worker_runs_the_longest_first_each_module_together():
    ordered = order([(["s1", "s2"], 1.0), (["l1", "l2"], 50.0)], 1)
    assert ordered == ["l1", "l2", "s1", "s2"]
