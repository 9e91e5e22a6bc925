"""How many tasks a fleet of bounded capacity can take at all: a maximum flow from task needs to
robot kinds (issue 51.5 — an instance whose `max_tasks_per_robot` leaves some task without a
capable robot with room is refused by `validate`, as the reference's routing would refuse it
at every run).

Tasks are grouped by what they need and robots by what they have, so the graph is as small as
the number of distinct needs times distinct capability sets, whatever the instance's size.
Dinic's algorithm (BFS levels, DFS blocking flows). Pure Python: an agent loads instances.
"""

from __future__ import annotations

from collections import deque
from typing import Callable, Hashable, Mapping


def serves_all(needs: Mapping[Hashable, int], room: Mapping[Hashable, int],
               capable: Callable[[Hashable, Hashable], bool]) -> int:
    """The most tasks served when `needs[n]` tasks need n, robots of kind k take `room[k]`
    tasks in all, and a task needing n may go to kind k when `capable(n, k)`."""
    left, right = list(needs), list(room)
    source, sink = 0, 1 + len(left) + len(right)
    graph: list[list[list]] = [[] for _ in range(sink + 1)]  # edge: [to, capacity, reverse]

    def edge(a: int, b: int, cap: int) -> None:
        graph[a].append([b, cap, len(graph[b])])
        graph[b].append([a, 0, len(graph[a]) - 1])

    for i, n in enumerate(left):
        edge(source, 1 + i, needs[n])
        for k, kind in enumerate(right):
            if capable(n, kind):
                edge(1 + i, 1 + len(left) + k, needs[n])
    for k, kind in enumerate(right):
        edge(1 + len(left) + k, sink, room[kind])
    total = 0
    while True:
        level = [-1] * len(graph)
        level[source] = 0
        queue = deque([source])
        while queue:
            a = queue.popleft()
            for b, cap, _ in graph[a]:
                if cap > 0 and level[b] < 0:
                    level[b] = level[a] + 1
                    queue.append(b)
        if level[sink] < 0:
            return total
        nxt = [0] * len(graph)
        while (pushed := _push(graph, level, nxt, source, sink, sum(needs.values()))) > 0:
            total += pushed


def _push(graph: list, level: list[int], nxt: list[int], a: int, sink: int, limit: int) -> int:
    """One augmenting path along the BFS levels (Dinic's blocking-flow step): the flow sent.
    Depth is at most 3 (source → need → kind → sink), so the recursion is shallow."""
    if a == sink:
        return limit
    while nxt[a] < len(graph[a]):
        e = graph[a][nxt[a]]
        b, cap, rev = e
        if cap > 0 and level[b] == level[a] + 1:
            sent = _push(graph, level, nxt, b, sink, min(limit, cap))
            if sent:
                e[1] -= sent
                graph[b][rev][1] += sent
                return sent
        nxt[a] += 1
    return 0
