"""Bounded instances (issue 51.5): what a walled instance costs to validate and to plan on.

    python benchmarks/instance_bounds.py [--walls N ...]

One JSON line per figure. Instances come from the delivery generator at fixed seeds (20 robots,
100 tasks in a 40 × 40 m room). Figures: `mrta instance validate`'s load (checks only, the
graph's edges unbuilt unless the world has walls to check reachability through), the
visibility graph's edges (bitangent pairs only), the whole travel matrix; the baseline, in the
same run, is the full visibility graph (every corner pair tested), as PathMap built it before."""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mrta_delivery.instance import load_document  # noqa: E402
from mrta_delivery.instances import DeliveryGeneratorParams, document_text, generate_document  # noqa: E402,E501


def timed(f) -> tuple[float, object]:
    t0 = time.perf_counter()
    out = f()
    return time.perf_counter() - t0, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--walls", type=int, nargs="+", default=[10, 20, 50])
    args = ap.parse_args()
    for walls in args.walls:
        p = DeliveryGeneratorParams(robots=20, tasks=100, walls=walls, room=(40.0, 40.0))
        with tempfile.TemporaryDirectory() as tmp:
            f = Path(tmp) / "i.yaml"
            f.write_text(document_text(generate_document(p, 0), ""))
            load_s, doc = timed(lambda: load_document(f))
        paths = doc.path_map()
        graph_s, edges = timed(lambda: paths.edges)
        full_s, full = timed(lambda: sum(paths.visible(a, b) for i, a in enumerate(paths.nodes)
                                         for b in paths.nodes[i + 1:]))
        matrix_s, _ = timed(doc.problem)
        print(json.dumps({"figure": "walled instance", "walls": walls, "nodes": len(paths.nodes),
                          "validate_load_s": round(load_s, 3),
                          "graph_edges_s": round(graph_s, 3),
                          "edges": sum(map(len, edges)) // 2,
                          "baseline_full_graph_s": round(full_s, 3), "full_edges": full,
                          "speedup": round(full_s / graph_s, 1) if graph_s else math.inf,
                          "problem_matrix_s": round(matrix_s, 3)}), flush=True)


if __name__ == "__main__":
    main()
