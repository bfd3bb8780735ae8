"""The stencil table of isosurface stuffing: every sign pattern covered, positive volumes, the parity rule."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from algorithms.meshing.isosurface_stuffing import stencils
from algorithms.meshing.isosurface_stuffing.fill import _parity_bit


def _patterns():
    return list(itertools.product("+-0", repeat=4))


def test_every_one_of_the_81_patterns_maps_to_a_stencil_or_to_nothing():
    indices = {stencils.pattern_index(signs) for signs in _patterns()}
    assert len(indices) == 81
    for index in range(256):
        assert (stencils.COUNTS[index] >= 0) == (index in indices)
    for signs in _patterns():
        index = stencils.pattern_index(signs)
        if "+" in signs:
            assert 1 <= stencils.COUNTS[index] <= 3 and stencils.STENCIL_OF[index] >= 0
        else:
            assert stencils.COUNTS[index] == 0 and stencils.STENCIL_OF[index] == -1
    assert sorted(set(stencils.STENCIL_OF[stencils.STENCIL_OF >= 0])) == list(range(12))
    assert len(stencils.STENCILS) == 12


def test_zero_and_positive_vertices_are_kept_and_negative_ones_never_used():
    for signs in _patterns():
        index = stencils.pattern_index(signs)
        for variant in range(1 << stencils.N_FACES[index]):
            used = set(stencils.TETS[index, variant, :stencils.COUNTS[index]].ravel())
            for v in range(4):
                assert (v in used) == (signs[v] in "+0" and "+" in signs)
            for code in used - {0, 1, 2, 3}:  # cut points only on edges with a + and a - end
                u, v = stencils.EDGE_ENDS[code - 4]
                assert {signs[u], signs[v]} == {"+", "-"}


@pytest.mark.parametrize("seed", range(3))
def test_every_output_tetrahedron_has_positive_volume_and_they_fill_the_positive_part(seed):
    rng = np.random.default_rng(seed)
    for signs in _patterns():
        index = stencils.pattern_index(signs)
        if "+" not in signs:
            continue
        cuts = [e for e, (u, v) in enumerate(stencils.EDGE_ENDS) if {signs[u], signs[v]} == {"+", "-"}]
        for _ in range(10):
            t = rng.uniform(0.02, 0.98, 6)
            if len(cuts) == 4:  # the four cut points coplanar, so the positive part is a convex polytope
                tau = rng.uniform(0.02, 0.98)
                for e, (u, v) in enumerate(stencils.EDGE_ENDS):
                    t[e] = tau if signs[u] == "+" else 1 - tau
            corners = [stencils.CANONICAL[v] for v in range(4) if signs[v] in "+0"]
            corners += [stencils.positions([4 + e], stencils.CANONICAL, t)[0] for e in cuts]
            expected = ConvexHull(np.array(corners)).volume
            for variant in range(1 << stencils.N_FACES[index]):
                volumes = [stencils._volume(stencils.positions(tet, stencils.CANONICAL, t))
                           for tet in stencils.TETS[index, variant, :stencils.COUNTS[index]]]
                assert min(volumes) > 0, (signs, variant)
                assert sum(volumes) == pytest.approx(expected, rel=1e-9)


def test_the_parity_rule_gives_one_diagonal_whichever_way_a_face_is_read():
    # slots: (grid, i, j, k); a face with an outer black edge A B along x and an inner apex, and one on the inner
    # grid; reading p1 and p2 the other way round must flip the bit (the same diagonal).
    for slots in (
        np.array([(0, 3, 4, 5), (0, 4, 4, 5), (1, 3, 3, 4), (1, 3, 4, 4)]),
        np.array([(1, 3, 3, 4), (1, 3, 4, 4), (0, 3, 4, 5), (0, 4, 4, 5)]),
    ):
        for m in (2, 3):
            assert _parity_bit(slots, 0, 1, m) != _parity_bit(slots, 1, 0, m)
    # the two parity faces of a ++-- tetrahedron choose diagonals from different ends (the paper's prism)
    slots = np.array([(0, 3, 4, 5), (0, 4, 4, 5), (1, 3, 3, 4), (1, 3, 4, 4)])
    assert _parity_bit(slots, 0, 1, 2) != _parity_bit(slots, 0, 1, 3)
