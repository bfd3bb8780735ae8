"""The stencil table of isosurface stuffing: 12 hand-made stencils, the 81 sign patterns by permutation, the parity
rule.

Method (source 002, section 4.2.4; Labelle & Shewchuk 2007, section 3): a BCC tetrahedron ``(A, B, C, D)`` with a
positive vertex is replaced by the part of it where ``f >= 0``, built from its lattice vertices and the cut points on
its edges. The table is indexed like source 002's: two bits per vertex sign (``0`` zero, ``1`` positive, ``2``
negative), ``index = sA << 6 | sB << 4 | sC << 2 | sD``, 256 entries of which 81 are sign patterns; the 16 patterns
without a positive vertex stay empty, the other 65 are generated from 12 stencils by permuting the vertices.

Vertex order and colours
------------------------
Our kernels enumerate each BCC tetrahedron as ``(A, B, C, D)`` where ``A -> B`` is a black edge of the outer grid,
``C -> D`` a black edge of the inner grid (both length ``h``) and the four other edges are red (length
``h sqrt(3) / 2``); ``(A, B, C, D)`` has positive volume. A stencil's output tetrahedra use vertex codes ``0-3`` for
``A, B, C, D`` and ``4-9`` for the cut points on the edges ``AB, AC, AD, BC, BD, CD``.

The 12 stencils (one per row of :data:`STENCILS`): four that keep the whole tetrahedron (no negative vertex, 0-3
zeros), three that keep one tetrahedron at the positive vertex (one positive and the rest negative or zero), the
truncated tetrahedron of three positive vertices (a prism of three tetrahedra), two positive and two negative
vertices joined by black edges or by a red edge (prisms), and two positive, one negative, one zero vertex with the
positive pair joined by a black or by a red edge (pyramids). Single-tetrahedron stencils do not depend on the edge
colours, so any vertex permutation maps them onto a pattern; the others depend on the colours and are permuted
only by the eight symmetries of the BCC tetrahedron that keep black edges black.

Quadrilaterals and the parity rule
----------------------------------
A quadrilateral arises on a lattice face (one black, two red edges) with two positive vertices ``p1, p2`` and a
negative one ``m``: ``(p1, p2, c(m, p2), c(m, p1))``. Both tetrahedra sharing the face must split it along the same
diagonal. When the face's black edge joins ``m`` to a positive vertex, the diagonal joins the cut point on that
black edge to the other positive vertex (a choice made by the face alone). When the black edge is ``p1 p2``, the
**parity rule** chooses: with ``b`` the black edge's axis and ``o1, o2`` the other two, let
``sigma(p1) = sign((p2 - p1)_b) * sign((m - p1)_o1) * sign((m - p1)_o2)``; the diagonal leaves ``p1`` (to
``c(m, p2)``) when ``sigma(p1) = -1`` for a black edge of the outer grid or ``+1`` for one of the inner grid, and
leaves ``p2`` otherwise. Exchanging ``p1`` and ``p2`` flips the sign of ``(p2 - p1)_b`` and nothing else, so both
tetrahedra of the face choose the same diagonal. Stencils with such faces (:data:`PARITY_STENCILS`) list the faces
and one tetrahedron set per combination of choices (bit ``f`` set: face ``f``'s diagonal leaves ``p2``).

Orientation: every output tetrahedron is written with positive volume for cut points anywhere inside their edges
(checked when the table is built, on the canonical BCC tetrahedron with cut parameters 0.5, and by the tests on
random parameters).

References
----------
F. Labelle and J. R. Shewchuk, "Isosurface stuffing: fast tetrahedral meshes with good dihedral angles", ACM
Transactions on Graphics 26(3), SIGGRAPH 2007, article 57. doi:10.1145/1276377.1276448.
Source 002 (K. Kähler, *Vergleich von Volumenmodellen*, MSc thesis, TU Kaiserslautern, about 2009; see
docs/references.md), section 4.2.4 "Implementierung der Stempel-Tabelle".
"""

from __future__ import annotations

import itertools

import numpy as np

A, B, C, D = 0, 1, 2, 3
#: The cut-point code of each edge ``(u, v)``, ``u < v``.
EDGE_CODE = {(0, 1): 4, (0, 2): 5, (0, 3): 6, (1, 2): 7, (1, 3): 8, (2, 3): 9}
#: The two vertices of each cut-point code 4-9.
EDGE_ENDS = np.array([(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)], dtype=np.int64)
#: Black edges of the canonical tetrahedron.
BLACK = frozenset({(0, 1), (2, 3)})
#: Sign codes of source 002.
ZERO, POSITIVE, NEGATIVE = 0, 1, 2
_SIGN_CODE = {"0": ZERO, "+": POSITIVE, "-": NEGATIVE}
MAX_TETS = 3
MAX_FACES = 2


def cut(u: int, v: int) -> int:
    """Vertex code of the cut point on the edge ``(u, v)``."""
    return EDGE_CODE[(min(u, v), max(u, v))]


def _c(u, v):
    return ("c", u, v)


# Each stencil: canonical signs of (A, B, C, D), whether it depends on the edge colours, its parity faces
# ((p1, p2, m) with p1 p2 black), and one list of tetrahedra per combination of parity choices. Vertices are 0-3 or
# ("c", u, v) for the cut point on the edge u v.
STENCILS = (
    # 1-4: no negative vertex: the tetrahedron itself.
    ("++++", False, (), ([(A, B, C, D)],)),
    ("+++0", False, (), ([(A, B, C, D)],)),
    ("++00", False, (), ([(A, B, C, D)],)),
    ("+000", False, (), ([(A, B, C, D)],)),
    # 5-7: one positive vertex, the others negative or zero: one tetrahedron at A.
    ("+---", False, (), ([(A, _c(A, B), _c(A, C), _c(A, D))],)),
    ("+--0", False, (), ([(A, _c(A, B), _c(A, C), D)],)),
    ("+-00", False, (), ([(A, _c(A, B), C, D)],)),
    # 8: three positive, D negative (its black edge is C D): prism; faces A C D and B C D take the diagonal from the
    # cut on the black edge; face A B D by parity.
    ("+++-", True, ((A, B, D),), (
        [(A, B, C, _c(C, D)), (A, B, _c(B, D), _c(C, D)), (A, _c(B, D), _c(A, D), _c(C, D))],  # from A
        [(A, B, C, _c(C, D)), (A, B, _c(A, D), _c(C, D)), (B, _c(B, D), _c(A, D), _c(C, D))],  # from B
    )),
    # 9: A B positive (black), C D negative (black): prism, faces A B C and A B D by parity.
    ("++--", True, ((A, B, C), (A, B, D)), (
        # A B C from A, A B D from A
        [(A, B, _c(B, C), _c(B, D)), (A, _c(A, C), _c(B, C), _c(B, D)), (A, _c(A, C), _c(B, D), _c(A, D))],
        # A B C from B, A B D from A
        [(_c(A, C), B, _c(B, C), _c(B, D)), (_c(A, C), A, B, _c(B, D)), (_c(A, C), A, _c(B, D), _c(A, D))],
        # A B C from A, A B D from B
        [(_c(B, C), A, _c(A, C), _c(A, D)), (_c(B, C), A, B, _c(A, D)), (_c(B, C), B, _c(B, D), _c(A, D))],
        # both from B
        [(B, A, _c(A, C), _c(A, D)), (B, _c(A, C), _c(B, C), _c(A, D)), (B, _c(B, C), _c(B, D), _c(A, D))],
    )),
    # 10: A C positive (red edge), B D negative: prism; faces A B C and A C D take the diagonals from the cuts on
    # the black edges A B and C D.
    ("+-+-", True, (), (
        [(_c(C, D), A, _c(A, B), _c(A, D)), (_c(C, D), A, C, _c(A, B)), (_c(C, D), C, _c(B, C), _c(A, B))],
    )),
    # 11: A B positive (black), C negative, D zero: pyramid over face A B C, by parity.
    ("++-0", True, ((A, B, C),), (
        [(D, A, B, _c(B, C)), (D, A, _c(B, C), _c(A, C))],  # from A
        [(D, A, B, _c(A, C)), (D, B, _c(B, C), _c(A, C))],  # from B
    )),
    # 12: A C positive (red edge), B negative, D zero: pyramid; face A B C takes the diagonal from the cut on the
    # black edge A B.
    ("+-+0", True, (), (
        [(D, A, C, _c(A, B)), (D, C, _c(B, C), _c(A, B))],
    )),
)

#: Indices of the stencils with parity faces.
PARITY_STENCILS = tuple(n for n, stencil in enumerate(STENCILS) if stencil[2])

#: Canonical BCC tetrahedron (unit h): A B along x on the outer grid, C D along y on the inner grid.
CANONICAL = np.array([(0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.5, -0.5, -0.5), (0.5, 0.5, -0.5)])


def pattern_index(signs) -> int:
    """Table index of four signs (``"+-0"`` characters or codes 0/1/2), source 002's bit layout."""
    codes = [_SIGN_CODE[s] if isinstance(s, str) else int(s) for s in signs]
    return (codes[0] << 6) | (codes[1] << 4) | (codes[2] << 2) | codes[3]


def _colour_preserving(perm) -> bool:
    return all((min(perm[u], perm[v]), max(perm[u], perm[v])) in BLACK for u, v in BLACK)


def _code(vertex, perm) -> int:
    if isinstance(vertex, tuple):
        return cut(perm[vertex[1]], perm[vertex[2]])
    return perm[vertex]


def positions(codes, corners, t) -> np.ndarray:
    """Positions of vertex codes on a tetrahedron with ``corners`` (4, 3) and cut parameters ``t`` (6,) along
    :data:`EDGE_ENDS` (from the first end)."""
    corners = np.asarray(corners, dtype=np.float64)
    out = []
    for code in codes:
        if code < 4:
            out.append(corners[code])
        else:
            u, v = EDGE_ENDS[code - 4]
            out.append(corners[u] + t[code - 4] * (corners[v] - corners[u]))
    return np.array(out)


def _volume(p) -> float:
    return float(np.dot(np.cross(p[1] - p[0], p[2] - p[0]), p[3] - p[0]) / 6.0)


def _oriented(codes) -> tuple:
    """``codes`` ordered so the tetrahedron has positive volume on the canonical tetrahedron (cuts at 0.5)."""
    volume = _volume(positions(codes, CANONICAL, np.full(6, 0.5)))
    if abs(volume) < 1e-12:
        raise ValueError(f"stencil tetrahedron {codes} is degenerate")
    return tuple(codes) if volume > 0 else (codes[1], codes[0], codes[2], codes[3])


def build_table(stencils=STENCILS):
    """The 256-entry table from the stencils by permutation.

    Returns
    -------
    counts : ndarray (256,) int64
        Output tetrahedra per pattern (-1 for indices that are not sign patterns, 0 for patterns without output).
    faces : ndarray (256, MAX_FACES, 3) int64
        Parity faces ``(p1, p2, m)`` of each pattern (vertex codes 0-3), -1 where unused.
    n_faces : ndarray (256,) int64
        Parity faces per pattern.
    tets : ndarray (256, 4, MAX_TETS, 4) int64
        Vertex codes of the output tetrahedra per pattern and parity variant (bit f: face f's diagonal leaves p2).
    stencil_of : ndarray (256,) int64
        Which stencil (row of ``stencils``) made each entry; -1 for empty ones.
    """
    counts = np.full(256, -1, dtype=np.int64)
    faces = np.full((256, MAX_FACES, 3), -1, dtype=np.int64)
    n_faces = np.zeros(256, dtype=np.int64)
    tets = np.full((256, 1 << MAX_FACES, MAX_TETS, 4), -1, dtype=np.int64)
    stencil_of = np.full(256, -1, dtype=np.int64)
    perms = list(itertools.permutations(range(4)))
    for signs in itertools.product("+-0", repeat=4):
        index = pattern_index(signs)
        counts[index] = 0
        if "+" not in signs:
            continue
        for number, (canonical, coloured, parity_faces, variants) in enumerate(stencils):
            match = None
            for perm in perms:  # perm maps a canonical vertex to an actual one
                if all(signs[perm[v]] == canonical[v] for v in range(4)) and (
                        not coloured or _colour_preserving(perm)):
                    match = perm
                    break
            if match is None:
                continue
            n = len(parity_faces)
            n_faces[index] = n
            for f, face in enumerate(parity_faces):
                faces[index, f] = [match[v] for v in face]
            for variant in range(1 << MAX_FACES):
                tet_list = variants[variant & ((1 << n) - 1)]
                for t, tet in enumerate(tet_list):
                    tets[index, variant, t] = _oriented([_code(v, match) for v in tet])
            counts[index] = len(variants[0])
            stencil_of[index] = number
            break
        else:
            raise ValueError(f"no stencil covers the sign pattern {''.join(signs)}")
    return counts, faces, n_faces, tets, stencil_of


COUNTS, FACES, N_FACES, TETS, STENCIL_OF = build_table()
