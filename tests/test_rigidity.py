"""Generic rigidity: which framework distances the detected links determine."""

import itertools

import numpy as np
import pytest

from phyloc.errors import ValidationError
from phyloc.network.rigidity import determined_pairs


def _laman_independent(edges):
    """Laman's count: every nonempty subset F' spans at least (|F'| + 3)/2 nodes."""
    for k in range(1, len(edges) + 1):
        for sub in itertools.combinations(edges, k):
            nodes = {x for e in sub for x in e}
            if k > 2 * len(nodes) - 3:
                return False
    return True


def _rigid_2d(nodes, edges):
    """Brute force: the graph on ``nodes`` has 2|S| − 3 Laman-independent edges."""
    need = 2 * len(nodes) - 3
    if len(nodes) == 1:
        return True
    if len(edges) < need:
        return False
    return any(_laman_independent(f) for f in itertools.combinations(edges, need))


def _determined_brute(n, edges, u, v):
    """(u, v) is determined iff some induced subgraph containing both is rigid (Laman)."""
    others = [x for x in range(n) if x not in (u, v)]
    for k in range(len(others) + 1):
        for extra in itertools.combinations(others, k):
            S = {u, v, *extra}
            if _rigid_2d(S, [e for e in edges if e[0] in S and e[1] in S]):
                return True
    return False


def test_plane_agrees_with_lamans_count_on_random_graphs():
    rng = np.random.default_rng(3)
    n = 5
    all_pairs = list(itertools.combinations(range(n), 2))
    seen = {True: 0, False: 0}
    for _ in range(25):
        edges = [e for e in all_pairs if rng.random() < 0.55]
        got = determined_pairs(n, edges, all_pairs, 2, rng)
        for (u, w), g in zip(all_pairs, got, strict=True):
            assert g == _determined_brute(n, edges, u, w), (edges, (u, w))
            seen[bool(g)] += 1
    assert seen[True] > 20 and seen[False] > 20  # both answers were exercised


def test_closed_forms():
    rng = np.random.default_rng(1)
    # the triangle flexes without its third side; the bowtie turns about its shared node
    assert determined_pairs(3, [[0, 1], [1, 2]], [[0, 2], [0, 1]], 2, rng).tolist() == [
        False,
        True,
    ]
    bowtie = [[0, 1], [1, 2], [0, 2], [2, 3], [3, 4], [2, 4]]
    got = determined_pairs(5, bowtie, [[0, 3], [1, 4], [0, 4], [0, 1]], 2, rng)
    assert got.tolist() == [False, False, False, True]
    # in space, K4 minus one side flexes (5 < 3·4 − 6 links)
    k4_minus = [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3]]
    assert determined_pairs(4, k4_minus, [[2, 3]], 3, rng).tolist() == [False]
    assert determined_pairs(4, k4_minus, [[2, 3]], 2, rng).tolist() == [True]
    # anchors: an agent linked to two anchors is fixed in the plane, to one it is not
    fixed = np.array([True, True, True, False])
    assert determined_pairs(4, [[3, 0], [3, 1]], [[3, 2]], 2, rng, fixed=fixed).tolist() == [True]
    assert determined_pairs(4, [[3, 0]], [[3, 2]], 2, rng, fixed=fixed).tolist() == [False]
    # no links: only anchor-anchor pairs are determined
    assert determined_pairs(4, [], [[0, 1], [0, 3]], 2, rng, fixed=fixed).tolist() == [True, False]


def test_answer_does_not_depend_on_the_generic_positions():
    edges = [[0, 1], [1, 2], [2, 3], [3, 0], [0, 2], [4, 5], [5, 0], [4, 1]]
    pairs = list(itertools.combinations(range(6), 2))
    a = determined_pairs(6, edges, pairs, 2, np.random.default_rng(10))
    b = determined_pairs(6, edges + edges[::-1], pairs, 2, np.random.default_rng(11))
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize(
    "edges, pairs, key",
    [([[0, 3]], [[0, 1]], "edges"), ([[0, 1]], [[2, 2]], "pairs"), ([[0, -1]], [[0, 1]], "edges")],
)
def test_bad_input_names_the_argument(edges, pairs, key):
    with pytest.raises(ValidationError, match=key):
        determined_pairs(3, edges, pairs, 2, np.random.default_rng(0))
