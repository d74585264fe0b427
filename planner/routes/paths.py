"""A small undirected graph and its simple-path searches, for the route network.

The route network has tens of nodes; importing networkx for it cost ~0.2 s of every
``pefsim plan``, a tenth of the command. :class:`Graph` keeps networkx's adjacency semantics
(neighbours in the order their edges were first added, one attribute dict per edge), and the
searches follow networkx 3's algorithms step by step (the depth-first enumeration of
``all_simple_paths``; Yen's ``shortest_simple_paths`` over its bidirectional Dijkstra, with the
same heap tie-breaks and the same sums), so they return the same paths in the same order
(``tests/planner/routes/test_paths.py`` compares them with networkx).
"""

from __future__ import annotations

from collections.abc import Iterator
from heapq import heappop, heappush
from itertools import count


class NoPath(Exception):
    """No path joins the two nodes."""


class Graph:
    """An undirected simple graph: ``adj[u][v]`` is the attribute dict of edge u-v (shared both ways)."""

    def __init__(self):
        self.adj: dict[str, dict[str, dict]] = {}
        self._order: list[tuple[str, str]] = []  # edges in the order first added

    def add_node(self, n: str) -> None:
        self.adj.setdefault(n, {})

    def add_edge(self, a: str, b: str, **attrs) -> None:
        """Add edge a-b (and its nodes), or update its attributes in place."""
        self.add_node(a)
        self.add_node(b)
        data = self.adj[a].get(b)
        if data is None:
            data = {}
            self.adj[a][b] = data
            self.adj[b][a] = data
            self._order.append((a, b))
        data.update(attrs)

    def has_edge(self, a: str, b: str) -> bool:
        return b in self.adj.get(a, {})

    def edge(self, a: str, b: str) -> dict:
        """Attribute dict of edge a-b (KeyError if none)."""
        return self.adj[a][b]

    def edges(self) -> list[tuple[str, str]]:
        """Each edge once, as networkx lists them: by node, then neighbour order."""
        seen, out = set(), []
        for u, nbrs in self.adj.items():
            out += [(u, v) for v in nbrs if v not in seen]
            seen.add(u)
        return out

    def weights(self, keep=None) -> dict[str, dict[str, float]]:
        """``{u: {v: weight}}`` in neighbour order, only the edges whose attribute dict ``keep`` accepts."""
        return {u: {v: d["weight"] for v, d in nbrs.items() if keep is None or keep(d)} for u, nbrs in self.adj.items()}


    def to_networkx(self):
        """Return the same graph as a :class:`networkx.Graph` (same node and neighbour order; imports networkx)."""
        import networkx as nx

        g = nx.Graph()
        g.add_nodes_from(self.adj)
        g.add_edges_from((a, b, self.adj[a][b]) for a, b in self._order)
        return g


def all_simple_paths(adj: dict[str, dict[str, float]], source: str, target: str) -> Iterator[list[str]]:
    """Generate every simple path from ``source`` to ``target`` (networkx's depth-first order)."""
    if source not in adj or target not in adj:
        raise KeyError(f"node {source if source not in adj else target!r} not in the graph")
    cutoff = len(adj) - 1
    current = {None: None}  # node -> the node before it (insertion order = the path)
    stack = [iter([(None, source)])]
    while stack:
        nxt = next((e for e in stack[-1] if e[1] not in current), None)
        if nxt is None:
            stack.pop()
            current.popitem()
            continue
        node = nxt[1]
        if node == target:
            yield [n for n in current if n is not None] + [node]
        if len(current) - 1 < cutoff and node != target and target not in current:
            current[node] = nxt[0]
            stack.append(iter([(node, w) for w in adj[node]]))


def shortest_simple_paths(adj: dict[str, dict[str, float]], source: str, target: str) -> Iterator[list[str]]:
    """Generate the simple paths from ``source`` to ``target``, shortest first by summed weight (Yen).

    Raises
    ------
    NoPath
        When ``target`` cannot be reached (on the first path).
    """
    if source not in adj or target not in adj:
        raise KeyError(f"node {source if source not in adj else target!r} not in the graph")

    def length(path):
        return sum(adj[u][v] for u, v in zip(path, path[1:], strict=False))

    found: list[list[str]] = []
    heap: list = []
    queued: set[tuple[str, ...]] = set()
    order = count()

    def push(cost, path):
        if tuple(path) not in queued:
            heappush(heap, (cost, next(order), path))
            queued.add(tuple(path))

    prev = None
    while True:
        if not prev:
            push(*_bidirectional_dijkstra(adj, source, target))
        else:
            ignore_nodes, ignore_edges = set(), set()
            for i in range(1, len(prev)):
                root = prev[:i]
                root_length = length(root)
                for path in found:
                    if path[:i] == root:
                        ignore_edges.add((path[i - 1], path[i]))
                try:
                    dist, spur = _bidirectional_dijkstra(adj, root[-1], target, ignore_nodes, ignore_edges)
                    push(root_length + dist, root[:-1] + spur)
                except NoPath:
                    pass
                ignore_nodes.add(root[-1])
        if not heap:
            return
        _, _, path = heappop(heap)
        queued.remove(tuple(path))
        yield path
        found.append(path)
        prev = path


def _bidirectional_dijkstra(adj, source, target, ignore_nodes=None, ignore_edges=None):
    """Bidirectional Dijkstra on an undirected weight dict, networkx 3's steps and tie-breaks: (length, path)."""
    if ignore_nodes and (source in ignore_nodes or target in ignore_nodes):
        raise NoPath(f"no path between {source} and {target}")
    if source == target:
        return 0, [source]

    def neighbours(v):
        for w in adj[v]:
            if ignore_nodes and w in ignore_nodes:
                continue
            if ignore_edges and ((v, w) in ignore_edges or (w, v) in ignore_edges):
                continue
            yield w

    dists = [{}, {}]
    paths = [{source: [source]}, {target: [target]}]
    fringe = [[], []]
    seen = [{source: 0}, {target: 0}]
    c = count()
    heappush(fringe[0], (0, next(c), source))
    heappush(fringe[1], (0, next(c), target))
    finalpath, finaldist = [], None
    direction = 1
    while fringe[0] and fringe[1]:
        direction = 1 - direction
        dist, _, v = heappop(fringe[direction])
        if v in dists[direction]:
            continue
        dists[direction][v] = dist
        if v in dists[1 - direction]:
            return finaldist, finalpath
        for w in neighbours(v):
            vw = dists[direction][v] + adj[v][w]
            if w in dists[direction]:
                continue  # weights are lengths >= 0: never shorter
            if w not in seen[direction] or vw < seen[direction][w]:
                seen[direction][w] = vw
                heappush(fringe[direction], (vw, next(c), w))
                paths[direction][w] = paths[direction][v] + [w]
                if w in seen[0] and w in seen[1]:
                    total = seen[0][w] + seen[1][w]
                    if finalpath == [] or finaldist > total:
                        finaldist = total
                        finalpath = paths[0][w] + paths[1][w][::-1][1:]
    raise NoPath(f"no path between {source} and {target}")
