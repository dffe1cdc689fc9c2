"""A lean single-threaded rclpy executor: what SingleThreadedExecutor does, at the cost of a wait.

`LeanExecutor` keeps one wait set and the lists of entities, made again only when a node adds or
removes one, waits, and runs every ready callback at once; waitables (the QoS and liveliness
event handlers) join the wait at most every WAITABLES_PERIOD while callbacks keep it busy. It
keeps rclpy's semantics otherwise (coroutines as Tasks, callback groups, guard conditions,
exceptions out of spin_once). Single-threaded: spin it from one thread; other threads may only
wake it (guard conditions, create_task, wake). A message round trip costs 0.22-0.29 ms instead of
0.74-1.06 ms; the measurements, and why not rclpy's EventsExecutor: docs/architecture.md.
"""
import time

from rclpy.exceptions import InvalidHandle
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.task import Task
from rclpy.utilities import timeout_sec_to_nsec
from rclpy.waitable import NumberOfEntities

_KINDS = ("subscription", "guard_condition", "timer", "client", "service")
WAITABLES_PERIOD = 0.05   # s


class _Snapshot:
    """The nodes' entities at one moment, with a wait set sized for them."""

    def __init__(self, executor):
        self.subscriptions, self.timers, self.clients, self.services, self.guards, self.waitables = ([] for _ in range(6))
        for node in executor.get_nodes():
            self.subscriptions += node.subscriptions
            self.timers += node.timers
            self.clients += node.clients
            self.services += node.services
            self.guards += node.guards
            self.waitables += node.waitables
        own = [executor._guard, executor._sigint_gc]
        count = NumberOfEntities(len(self.subscriptions), len(self.guards) + len(own), len(self.timers),
                                 len(self.clients), len(self.services))
        for waitable in self.waitables:
            count += waitable.get_num_entities()
        self.wait_set = _rclpy.WaitSet(count.num_subscriptions, count.num_guard_conditions, count.num_timers,
                                       count.num_clients, count.num_services, count.num_events,
                                       executor.context.handle)
        # (entity, its handle's pointer): the pointer is what the wait set reports ready
        self.entries = {kind: [(e, e.handle.pointer) for e in entities] for kind, entities in (
            ("subscription", self.subscriptions), ("timer", self.timers), ("client", self.clients),
            ("service", self.services), ("guard_condition", self.guards))}
        self.own_guards = [(g, g.handle.pointer) for g in own]
        self.add = {"subscription": self.wait_set.add_subscription, "timer": self.wait_set.add_timer,
                    "client": self.wait_set.add_client, "service": self.wait_set.add_service,
                    "guard_condition": self.wait_set.add_guard_condition}

    def fill(self, busy_groups, waitables):
        """Put the entities in the wait set (leaving out those of a group that cannot run now, and
        the waitables unless `waitables`); returns the waitables put in."""
        wait_set = self.wait_set
        wait_set.clear_entities()
        for kind, entries in self.entries.items():
            add = self.add[kind]
            for entity, _ in entries:
                if not busy_groups or entity.callback_group.can_execute(entity):
                    add(entity.handle)
        for guard, _ in self.own_guards:
            wait_set.add_guard_condition(guard.handle)
        added = []
        if waitables:
            for waitable in self.waitables:
                if not busy_groups or waitable.callback_group.can_execute(waitable):
                    waitable.add_to_wait_set(wait_set)
                    added.append(waitable)
        return added


class LeanExecutor(Executor):
    """A single-threaded executor that reuses its wait set (see the module's docstring)."""

    def __init__(self, *, context=None):
        super().__init__(context=context)
        self._snapshot = None
        self._waitables_due = 0.0   # time.monotonic() from which waitables join the wait

    def wake(self):
        self._snapshot = None   # a node added or removed an entity
        super().wake()

    def add_node(self, node):
        self._snapshot = None
        return super().add_node(node)

    def remove_node(self, node):
        self._snapshot = None
        super().remove_node(node)

    def spin_once(self, timeout_sec=None):
        """Wait up to `timeout_sec` (None or negative: for ever; 0: not at all) for work, and do
        all of it: the ready callbacks, and the steps of coroutines and tasks in progress."""
        if self._is_shutdown:
            return
        self._run_tasks()
        timeout_ns = timeout_sec_to_nsec(timeout_sec)
        deadline = None if timeout_ns < 0 else time.monotonic() + timeout_ns / 1e9
        # A wait without the waitables ends when they are due: then wait again, with them.
        while not self._wait_and_execute(deadline) and not self._is_shutdown:
            if deadline is not None and time.monotonic() >= deadline:
                return

    def _wait_and_execute(self, deadline):
        """One wait (until `deadline`, or until the waitables are due); runs what is ready and
        says whether anything was."""
        now = time.monotonic()
        with_waitables = now >= self._waitables_due
        ends = [t for t in (deadline, None if with_waitables else self._waitables_due) if t is not None]
        timeout_ns = int(max(0.0, min(ends) - now) * 1e9) if ends else -1
        snapshot = self._snapshot
        try:
            if snapshot is None:
                snapshot = self._snapshot = _Snapshot(self)
            waitables = snapshot.fill(bool(self._tasks), with_waitables)
        except InvalidHandle:   # an entity went away since the snapshot: take a new one
            snapshot = self._snapshot = _Snapshot(self)
            waitables = snapshot.fill(bool(self._tasks), with_waitables)
        wait_set = snapshot.wait_set
        wait_set.wait(timeout_ns)
        if self._is_shutdown:
            return True
        if not self._context.ok():
            raise ExternalShutdownException()
        ready = {kind: set(wait_set.get_ready_entities(kind)) for kind in _KINDS}
        anything = any(ready.values())
        # The order of rclpy's executors: waitables, timers, subscriptions, guards, clients, services.
        if with_waitables:
            self._waitables_due = time.monotonic() + WAITABLES_PERIOD
        for waitable in waitables:
            try:
                if not waitable.is_ready(wait_set):
                    continue
            except InvalidHandle:
                continue
            anything = True
            self._execute(waitable, self._take_waitable)
        for timer, pointer in snapshot.entries["timer"]:
            if pointer in ready["timer"]:
                try:
                    if not timer.handle.is_timer_ready():   # (rcl reports a cancelled timer ready)
                        continue
                except (InvalidHandle, _rclpy.RCLError):   # destroyed by a callback of this very wait
                    continue
                self._execute(timer, self._take_timer)
        for kind, take in (("subscription", self._take_subscription), ("guard_condition", self._take_guard_condition),
                           ("client", self._take_client), ("service", self._take_service)):
            for entity, pointer in snapshot.entries[kind]:
                if pointer in ready[kind]:
                    self._execute(entity, take)
        return anything

    def spin_once_until_future_complete(self, future, timeout_sec=None):
        self.spin_once(getattr(timeout_sec, "timeout", timeout_sec))

    def _execute(self, entity, take):
        """Take the entity's work and run its callback; a coroutine that has to wait goes on as a
        task (its callback group stays busy until it ends, as in rclpy's executors)."""
        group = entity.callback_group
        if not group.beginning_execution(entity):
            return
        call = take(entity)   # rclpy's take functions return None for a destroyed entity or no data
        if call is None:
            group.ending_execution(entity)
            return

        async def run():
            try:
                await call()
            finally:
                group.ending_execution(entity)
        coroutine = run()
        try:
            coroutine.send(None)   # a plain callback runs to its end here (an exception comes out)
        except StopIteration:
            return
        # It awaits something: an rclpy Task resumes it at every spin from now on.
        with self._tasks_lock:
            self._tasks.append((Task(coroutine, executor=self), entity, None))

    def _run_tasks(self):
        """Resume every task and coroutine in progress once; an exception in one comes out here."""
        if not self._tasks:
            return
        with self._tasks_lock:
            tasks = list(self._tasks)
        for task, _, _ in tasks:
            if not task.done() and not task.executing():
                task()
        with self._tasks_lock:
            self._tasks = [entry for entry in self._tasks if not entry[0].done()]
        for task, _, _ in tasks:
            if task.done() and task.exception() is not None:
                raise task.exception()
