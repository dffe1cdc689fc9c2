"""A line to wait in for a busy testbed: first come, first served. Plain Python, no ROS.

The simulator keeps one: a start that finds the testbed busy (or others waiting before it) joins
the line with a ticket, when the client asked to wait, and asks again with it every moment; the
first in line starts when the testbed is free. A client that stops asking for `lease` seconds
(Ctrl-C, killed, gone) leaves the line by itself.
"""
import secrets
from collections import OrderedDict


class Line:
    def __init__(self, lease):
        self.lease = lease
        self.entries = OrderedDict()   # ticket -> [holder, last time it asked]

    def prune(self, now):
        for ticket in [t for t, (_, seen) in self.entries.items() if now - seen > self.lease]:
            del self.entries[ticket]

    def join(self, ticket, holder, now):
        """Keep `ticket`'s place (asking again), or join at the end with a new ticket; returns it."""
        if ticket in self.entries:
            self.entries[ticket][1] = now
            return ticket
        ticket = secrets.token_hex(8)
        self.entries[ticket] = [holder, now]
        return ticket

    def place(self, ticket):
        """1: next; 0: not in line."""
        for k, each in enumerate(self.entries, start=1):
            if each == ticket:
                return k
        return 0

    def first(self):
        return next(iter(self.entries), None)

    def leave(self, ticket):
        self.entries.pop(ticket, None)

    def holders(self):
        return [holder for holder, _ in self.entries.values()]
