"""How evenly a team shared its work (issue 50: one robot doing all the work while four stand
idle, rmf_task#127): the Gini coefficient of a quantity over robots.

    G = Σ_i Σ_j |x_i − x_j| / (2 n Σ_i x_i)

0 when every robot did the same, (n − 1)/n when one robot did everything — the population form,
not the sample form (× n/(n − 1)): a team is the whole population, and the population form is the
one Open-RMF's and the fair-allocation literature's figures use. A team that did nothing at all
is perfectly even (0), not undefined: nobody was favoured. Robots that were never given work
count as zeros — leaving them out would hide exactly the unfairness the figure is for.
"""

from __future__ import annotations

import math
from typing import Iterable


def gini(values: Iterable[float]) -> float:
    """The Gini coefficient of non-negative `values` (ValueError for a negative or non-finite
    one, or none at all); computed sorted, in O(n log n): G = (2 Σ_k k·x_(k)) / (n Σ x) − (n + 1)/n
    with x_(k) ascending, k from 1."""
    xs = sorted(float(v) for v in values)
    if not xs:
        raise ValueError("the Gini coefficient of no robots")
    if xs[0] < 0 or not math.isfinite(xs[-1]):
        raise ValueError(f"the Gini coefficient takes non-negative finite values, got {xs[0]!r} "
                         f"… {xs[-1]!r}")
    n, total = len(xs), math.fsum(xs)
    if total == 0:
        return 0.0
    ranked = math.fsum((k + 1) * x for k, x in enumerate(xs))
    return max(0.0, 2 * ranked / (n * total) - (n + 1) / n)
