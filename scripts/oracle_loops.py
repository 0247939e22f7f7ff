#!/usr/bin/env python3
"""Independent oracle for isotopo's handle loops (test-only; shares no code with the Rust crate).

It reads a mesh written by `isotopo mesh` and rebuilds, from the mesh alone, the graph on which
isotopo measures loops, the Z/2 homology of the surface, the systole (shortest non-trivial closed
walk) and shortest closed walks crossing a given cycle an odd number of times. Against these it
checks `isotopo analyze` (the Reeb and cross loops of every handle) and `isotopo simplify` (no
handle shorter than tau left).

Method
------
1. Mesh -> grid. Every vertex lies on a grid edge whose samples are on opposite sides of the
   isovalue. Its voxel coordinates (inverse affine) have two integer coordinates and one
   fractional one; the vertex is keyed by the edge's lower end and axis, (i, j, k, axis). isotopo
   clamps the interpolation fraction to [0.001, 0.999], so the fractional coordinate is never
   closer than 1e-3 to an integer; a vertex for which the float32 rounding makes this unclear is
   reported as an error rather than guessed.
2. Mesh facts, checked on every input (an OracleError says which one failed): triangles
   non-degenerate, every edge in exactly two triangles with opposite directions (closed,
   consistently oriented), every vertex's link a single cycle (2-manifold); distinct vertices on
   distinct grid edges; the three grid edges of a triangle are edges of one unit cube (lower
   corner = componentwise minimum of their lower ends), and never all in one face of it (that
   cube would be ambiguous; it does not happen with isotopo's case table); with the volume at
   hand, the vertices are exactly the crossing grid edges and sit at the linear interpolation.
3. Pieces: the triangles of one cube, connected through shared mesh edges. Each must be a disk
   (Euler characteristic 1, one boundary loop) or a tube (an annulus: 0, two loops), every
   boundary edge a segment on the face between two face-adjacent cubes, and every vertex must lie
   in exactly four pieces, one in each cube around its grid edge.
4. The surface graph (the paper's "voxel edges", what isotopo measures loops on):
     vertices = mesh vertices;
     edges    = (a) every mesh edge on the boundary of a piece (the segments on cube faces), and
                (b) every mesh edge interior to a tube piece (isotopo takes exactly the
                    triangulation's diagonals through a tube, which no face path can cross).
   Mesh edges interior to disk pieces are NOT graph edges. Lengths: 1 per edge ("edges") or the
   Euclidean distance of the two interpolated vertex positions in world mm ("mm").
5. Homology over Z/2, per connected component, by tree-cotree on the whole triangulation: a
   spanning tree T of the vertices over all mesh edges, a spanning tree of the triangles over the
   dual of the edges not in T, and the 2g edges left over. Every mesh edge gets a vector in
   (Z/2)^(2g) (a Python int used as a bitset; bits are numbered globally, so components never
   mix): tree edges 0, leftover edge k the unit vector e_k, cotree edges fixed by making every
   triangle's boundary sum to 0 (peeling dual-tree leaves towards the root; the root's own
   boundary must then sum to 0 too, which is checked). The class of a closed walk is the XOR of
   its edges' vectors: this map kills boundaries and sends the fundamental cycle of leftover edge
   k to e_k, so it is an isomorphism H1(S; Z/2) -> (Z/2)^(2g) and a walk is non-trivial (for a
   simple cycle: non-separating) iff its class is non-zero. 2g = 2 - chi is checked per
   component.
6. Systole, exact: for a source v, a shortest-path tree; every graph edge (a, b) gives the closed
   walk tree(v..a) + ab + tree(b..v) of length d(a) + w + d(b) and class c(a) ^ c(b) ^ h(ab).
   If C is a shortest non-trivial cycle through v, C is the XOR of the fundamental cycles of its
   non-tree edges, so one of them is non-trivial, and its length is at most |C| (both tree paths
   are no longer than the arcs of C they replace). Hence the minimum over all sources of the
   non-trivial candidates is the systole. Pruning, all exact: (a) sources are only the vertices
   of 2g graph cycles whose classes span H1 (fundamental cycles of a breadth-first tree, shortest
   first): C pairs oddly with one of them (the intersection form is non-degenerate), so they share
   a vertex; (b) to beat the current best B, every vertex of C is within |C|/2 < B/2 of v along
   C, so each search stops at radius B/2; (c) once v has been a source, every cycle through v is
   accounted for, so later searches avoid v (the first source met on C still sees all of C).
   Components of genus 0 are skipped.
7. Odd crossing with a simple cycle Z: at each vertex z of Z (with Z arriving from p and leaving
   to q), the mesh's triangle fan orders z's neighbours counter-clockwise; the graph edges
   strictly between q and p in that order are on Z's left and are "marked" at z (Z's own edges
   never are). An edge's parity is the number of its marked ends mod 2; a walk's parity is the sum
   over its edges, which is its algebraic intersection number with Z mod 2 (with Z pushed slightly to
   its left, so that walks along Z count as on its right). A closed walk crossing Z oddly must pass through Z, so the shortest one is
   min over s in Z of the shortest path from (s, 0) to (s, 1) in the double cover whose sheet
   flips on odd edges (with the same exact pruning: stop at the best so far, avoid sources done).
   A minimal walk of either search is a simple cycle (otherwise it splits into two shorter closed
   walks, one of them still non-trivial / odd), which is asserted.

Run `python3 scripts/oracle_loops.py -h`; the self-tests are scripts/test_oracle_loops.py.
"""

import argparse
import heapq
import json
import math
import os
import subprocess
import sys
import tempfile
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

ROOT = Path(__file__).resolve().parent.parent
METRICS = ("edges", "mm")


class OracleError(Exception):
    """A mesh fact or an input that does not hold (the message says which)."""


def _fail(msg):
    raise OracleError(msg)


# --------------------------------------------------------------------------------------------
# Inputs: PLY, volumes, the isotopo binary
# --------------------------------------------------------------------------------------------


def read_ply(path):
    """(vertices float64 (n, 3), triangles int64 (m, 3)) of isotopo's binary little-endian PLY."""
    data = Path(path).read_bytes()
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        _fail(f"{path}: not a PLY file")
    lines = [l for l in data[:end].decode("ascii").split("\n") if l and not l.startswith("comment")]
    want = ["ply", "format binary_little_endian 1.0", None, "property float x", "property float y",
            "property float z", None, "property list uchar int vertex_indices"]
    if len(lines) != len(want) or any(w is not None and l != w for l, w in zip(lines, want)):
        _fail(f"{path}: unexpected PLY header {lines}")
    if not (lines[2].startswith("element vertex ") and lines[6].startswith("element face ")):
        _fail(f"{path}: unexpected PLY elements {lines[2]!r}, {lines[6]!r}")
    nv, nf = int(lines[2].split()[2]), int(lines[6].split()[2])
    body = data[end + len(b"end_header\n"):]
    if len(body) != 12 * nv + 13 * nf:
        _fail(f"{path}: body has {len(body)} bytes, header says {12 * nv + 13 * nf}")
    V = np.frombuffer(body, "<f4", count=3 * nv).reshape(nv, 3).astype(np.float64)
    faces = np.frombuffer(body, np.dtype([("n", "u1"), ("v", "<i4", (3,))]), count=nf, offset=12 * nv)
    if nf and (faces["n"] != 3).any():
        _fail(f"{path}: a face is not a triangle")
    return V, faces["v"].astype(np.int64).reshape(nf, 3)


def load_volume(path):
    """(samples float64 indexed [x, y, z], voxel->world affine). NIfTI and the other formats
    nibabel reads use nibabel (scaling applied, img.affine); .npy has the identity affine."""
    p = str(path)
    if p.endswith(".npy"):
        data, affine = np.load(p), np.eye(4)
    else:
        import nibabel as nib
        img = nib.load(p)
        data, affine = img.get_fdata(dtype=np.float64), np.asarray(img.affine, float)
    data = np.asarray(data, dtype=np.float64)
    while data.ndim > 3 and data.shape[-1] == 1:
        data = data[..., 0]
    if data.ndim != 3:
        _fail(f"{path}: a 3-D volume is needed, found shape {data.shape}")
    return data, affine


def isotopo_bin():
    exe = os.environ.get("ISOTOPO", str(ROOT / "target" / "release" / "isotopo"))
    if not Path(exe).exists():
        _fail(f"{exe} not found: run `cargo build --release` (or set ISOTOPO)")
    return exe


def run_isotopo(*args):
    cmd = [isotopo_bin(), *map(str, args)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        _fail(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stderr}")
    return p.stdout


def _surface_args(iso, conn, inside):
    return ["--iso", repr(float(iso)), "--connectivity", str(conn), "--inside", inside, "-q"]


def mesh_volume(vol, iso, out, conn=6, inside="above"):
    """Runs `isotopo mesh` into the PLY file `out`; returns its path."""
    out = Path(out)
    run_isotopo("mesh", vol, *_surface_args(iso, conn, inside), "-o", out)
    return out


# --------------------------------------------------------------------------------------------
# The mesh and its facts
# --------------------------------------------------------------------------------------------


@dataclass
class Mesh:
    V: np.ndarray            # (n, 3) world mm
    F: np.ndarray            # (m, 3) vertex indices, counter-clockwise seen from one side
    affine: np.ndarray       # voxel -> world
    keys: np.ndarray         # (n, 4) grid edge of each vertex: lower end i, j, k and axis
    key_index: dict          # (i, j, k, axis) -> vertex
    edges: np.ndarray        # (E, 2) mesh edges, u < v
    edge_index: dict         # (u, v), u < v -> edge id
    edge_tris: np.ndarray    # (E, 2) the two triangles of each edge
    tri_edges: np.ndarray    # (m, 3) edges (F0 F1), (F1 F2), (F2 F0)
    ring: list               # ring[v]: neighbours of v in counter-clockwise order (triangle fan)
    cube: np.ndarray         # (m, 3) lower corner of each triangle's cube
    piece: np.ndarray        # (m,) piece of each triangle
    piece_is_tube: np.ndarray  # (pieces,) bool
    comp_v: np.ndarray       # (n,) connected component of each vertex
    comp_chi: list           # Euler characteristic of each component
    mesh_checks: list = field(default_factory=list)  # what was verified, for reports

    @property
    def n(self):
        return len(self.V)

    def edge(self, u, v):
        """Mesh edge id joining u and v, or None."""
        return self.edge_index.get((u, v) if u < v else (v, u))

    def midpoint(self, v):
        """Midpoint of v's grid edge, voxel coordinates (isotopo's `points`)."""
        i, j, k, a = (int(x) for x in self.keys[v])
        p = [float(i), float(j), float(k)]
        p[a] += 0.5
        return p

    def vertex_of_point(self, p):
        """The vertex on the grid edge whose midpoint is p (voxel coordinates), or None; raises
        if p is not the midpoint of a grid edge."""
        p = np.asarray(p, float)
        half = np.abs(p - np.floor(p) - 0.5) < 1e-6
        whole = np.abs(p - np.round(p)) < 1e-6
        if half.sum() != 1 or whole.sum() != 2:
            _fail(f"point {list(p)} is not the midpoint of a grid edge (one half-integer coordinate)")
        a = int(np.argmax(half))
        lo = np.round(p).astype(np.int64)
        lo[a] = int(math.floor(p[a]))
        return self.key_index.get((int(lo[0]), int(lo[1]), int(lo[2]), a))


def _grid_edges(V, affine):
    """Key (lower end, axis) of each vertex's grid edge, from its voxel coordinates."""
    n = len(V)
    inv = np.linalg.inv(affine)
    vox = V @ inv[:3, :3].T + inv[:3, 3]
    if n == 0:
        return np.zeros((0, 4), np.int64)
    spacing = np.linalg.norm(affine[:3, :3], axis=0).min()
    # float32 world coordinates, seen in voxel units: a few ulps of the largest coordinate.
    tol = 1e-5 + 2e-7 * (np.abs(V).max() + 1.0) / spacing
    dist = np.abs(vox - np.round(vox))
    order = np.sort(dist, axis=1)
    bad = np.nonzero((order[:, 1] > tol) | (order[:, 2] < 4 * tol))[0]
    if len(bad):
        v = int(bad[0])
        _fail(f"{len(bad)} vertices are not clearly on one grid edge (tolerance {tol:.2g}), e.g. "
              f"vertex {v} at voxel {vox[v].tolist()}: two coordinates must be integers and one "
              "fractional (at least 1e-3 from an integer)")
    axis = np.argmax(dist, axis=1)
    lower = np.round(vox).astype(np.int64)
    rows = np.arange(n)
    lower[rows, axis] = np.floor(vox[rows, axis]).astype(np.int64)
    return np.column_stack([lower, axis])


def _topology(F, n):
    """Edges, edge<->triangle incidence; checks closed, oriented, non-degenerate."""
    m = len(F)
    if m and (F.min() < 0 or F.max() >= n):
        _fail("a triangle refers to a vertex that does not exist")
    if ((F[:, 0] == F[:, 1]) | (F[:, 1] == F[:, 2]) | (F[:, 2] == F[:, 0])).any():
        _fail("a triangle repeats a vertex")
    d = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])  # row s*m + t: slot s of t
    dk = d[:, 0] * n + d[:, 1]
    if len(np.unique(dk)) != len(dk):
        _fail("a directed edge occurs in two triangles: not consistently oriented, or not manifold")
    u, v = d.min(axis=1), d.max(axis=1)
    uniq, inv, counts = np.unique(u * n + v, return_inverse=True, return_counts=True)
    if (counts != 2).any():
        _fail(f"{int((counts != 2).sum())} edges are not in exactly two triangles: not closed")
    edges = np.column_stack([uniq // n, uniq % n])
    order = np.argsort(inv, kind="stable")
    edge_tris = (order % m).reshape(-1, 2)
    tri_edges = inv.reshape(3, m).T
    return edges, edge_tris, tri_edges


def _rings(F, n):
    """Neighbours of each vertex counter-clockwise; checks every vertex link is one cycle."""
    nxt = [dict() for _ in range(n)]
    for a, b, c in F.tolist():
        # Triangle (a, b, c): turning counter-clockwise round a, edge ab is followed by edge ac.
        nxt[a][b] = c
        nxt[b][c] = a
        nxt[c][a] = b
    rings = []
    for v in range(n):
        if not nxt[v]:
            _fail(f"vertex {v} is in no triangle")
        start = next(iter(nxt[v]))
        ring, x = [start], nxt[v][start]
        while x != start and len(ring) <= len(nxt[v]):
            ring.append(x)
            x = nxt[v].get(x)
            if x is None:
                _fail(f"vertex {v}: its triangle fan is not closed")
        if len(ring) != len(nxt[v]):
            _fail(f"vertex {v}: its link is not one cycle (not a 2-manifold there)")
        rings.append(ring)
    return rings


def _cubes(keys, F):
    """Lower corner of the unit cube holding each triangle's three grid edges."""
    ends, axes = keys[F][:, :, :3], keys[F][:, :, 3]  # (m, 3, 3), (m, 3)
    cube = ends.min(axis=1)
    off = ends - cube[:, None, :]
    along = np.take_along_axis(off, axes[:, :, None], axis=2)[:, :, 0]
    bad = np.nonzero(((off < 0) | (off > 1)).any(axis=(1, 2)) | (along != 0).any(axis=1))[0]
    if len(bad):
        t = int(bad[0])
        _fail(f"{len(bad)} triangles do not lie in one unit cube, e.g. triangle {t} on grid edges "
              f"{keys[F[t]].tolist()}")
    for b in range(3):
        # All three edges in the cube's face b = cube[b]: the cube below shares them.
        flat = ((off[:, :, b] == 0) & (axes != b)).all(axis=1)
        if flat.any():
            t = int(np.nonzero(flat)[0][0])
            _fail(f"triangle {t} lies in a face shared by two cubes (grid edges "
                  f"{keys[F[t]].tolist()}): its piece is ambiguous")
    return cube


def _pieces(mesh_edges, edge_tris, cube, F, keys, n):
    """Piece of each triangle and whether it is a tube; checks the piece facts."""
    m = len(F)
    t0, t1 = edge_tris[:, 0], edge_tris[:, 1]
    same = (cube[t0] == cube[t1]).all(axis=1)
    g = coo_matrix((np.ones(int(same.sum())), (t0[same], t1[same])), shape=(m, m))
    npieces, piece = connected_components(g, directed=False)

    # Boundary edges are segments on the face between two face-adjacent cubes.
    bnd = np.nonzero(~same)[0]
    step = cube[t1[bnd]] - cube[t0[bnd]]
    if not (np.abs(step).sum(axis=1) == 1).all():
        _fail("a piece boundary edge joins triangles of cubes that are not face-adjacent")
    b_axis = np.argmax(np.abs(step), axis=1)
    face = np.maximum(cube[t0[bnd], b_axis], cube[t1[bnd], b_axis])
    for end in (0, 1):
        k = keys[mesh_edges[bnd, end]]
        if ((k[:, 3] == b_axis) | (k[np.arange(len(bnd)), b_axis] != face)).any():
            _fail("a piece boundary edge does not lie in the face between its two cubes")

    # Per piece: Euler characteristic and boundary loops. Disk (1, 1) or tube (0, 2).
    tri_count = np.bincount(piece, minlength=npieces)
    bnd_edges = [[] for _ in range(npieces)]
    for e in bnd.tolist():
        u, v = int(mesh_edges[e, 0]), int(mesh_edges[e, 1])
        bnd_edges[piece[t0[e]]].append((u, v))
        bnd_edges[piece[t1[e]]].append((u, v))
    verts = [set() for _ in range(npieces)]
    for t, tri in enumerate(F.tolist()):
        verts[piece[t]].update(tri)
    is_tube = np.zeros(npieces, bool)
    for p in range(npieces):
        adj = {}
        for u, v in bnd_edges[p]:
            adj.setdefault(u, []).append(v)
            adj.setdefault(v, []).append(u)
        if any(len(x) != 2 for x in adj.values()) or set(adj) != verts[p]:
            _fail(f"piece {p} (cube {cube[np.nonzero(piece == p)[0][0]].tolist()}): its boundary "
                  "is not a union of cycles through all its vertices")
        loops, seen = 0, set()
        for s in adj:
            if s not in seen:
                loops += 1
                stack = [s]
                while stack:
                    x = stack.pop()
                    if x not in seen:
                        seen.add(x)
                        stack.extend(adj[x])
        nb = len(bnd_edges[p])
        interior = (3 * tri_count[p] - nb) // 2
        chi = len(verts[p]) - nb - interior + tri_count[p]
        if (chi, loops) not in ((1, 1), (0, 2)):
            _fail(f"piece {p}: Euler characteristic {chi} with {loops} boundary loops: neither a "
                  "disk nor a tube")
        is_tube[p] = loops == 2

    # Every vertex: four pieces, in the four distinct cubes round its grid edge.
    corner_v = F.reshape(-1)
    corner_p = np.repeat(piece, 3)
    vp = np.unique(corner_v * npieces + corner_p)
    if not (np.bincount(vp // npieces, minlength=n) == 4).all():
        _fail("a vertex does not lie in exactly four pieces")
    cid = np.unique(np.column_stack([corner_v, np.repeat(cube, 3, axis=0)]), axis=0)
    if not (np.bincount(cid[:, 0], minlength=n) == 4).all():
        _fail("a vertex's four pieces are not in four distinct cubes")
    return piece, is_tube


def _check_against_volume(keys, vox_frac, data, iso, inside):
    """The vertices are exactly the crossing grid edges (inside = value > iso, or < with
    inside='below'; NaN and the padding outside), at the linear interpolation (clamped to
    [0.001, 0.999], 0.5 where a sample is NaN or padding)."""
    pad = np.full(tuple(s + 2 for s in data.shape), np.nan)
    pad[1:-1, 1:-1, 1:-1] = data
    with np.errstate(invalid="ignore"):
        ins = pad > iso if inside == "above" else pad < iso
    want = set()
    for a in range(3):
        lo = [slice(0, -1) if b == a else slice(None) for b in range(3)]
        hi = [slice(1, None) if b == a else slice(None) for b in range(3)]
        cross = np.argwhere(ins[tuple(lo)] != ins[tuple(hi)]) - 1
        want.update((int(i), int(j), int(k), a) for i, j, k in cross)
    have = set(map(tuple, keys.tolist()))
    if have != want:
        miss, extra = want - have, have - want
        _fail(f"mesh vertices are not the crossing grid edges: {len(miss)} crossing edges without "
              f"a vertex (e.g. {sorted(miss)[:3]}), {len(extra)} vertices on non-crossing edges "
              f"(e.g. {sorted(extra)[:3]})")
    p = keys[:, :3] + 1
    q = p.copy()
    q[np.arange(len(p)), keys[:, 3]] += 1
    va, vb = pad[tuple(p.T)], pad[tuple(q.T)]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (iso - va) / (vb - va)
    t = np.where(np.isfinite(t), np.clip(t, 0.001, 0.999), 0.5)
    err = np.abs(t - vox_frac)
    if len(err) and err.max() > 2e-4:
        v = int(np.argmax(err))
        _fail(f"vertex {v} on grid edge {keys[v].tolist()} is at fraction {vox_frac[v]:.6f}, "
              f"linear interpolation gives {t[v]:.6f}")


def load_mesh(ply, affine=None, volume=None, iso=None, inside="above"):
    """Reads an `isotopo mesh` PLY and checks the mesh facts (module docstring, 1-3). `affine` is
    the volume's voxel->world matrix (identity if None). With `volume` (samples array) and `iso`,
    also checks that the vertices are the crossing grid edges at the interpolated positions."""
    V, F = read_ply(ply)
    affine = np.eye(4) if affine is None else np.asarray(affine, float)
    n = len(V)
    keys = _grid_edges(V, affine)
    key_index = {tuple(k): v for v, k in enumerate(keys.tolist())}
    if len(key_index) != n:
        _fail("two vertices lie on the same grid edge")
    checks = ["vertices on distinct grid edges"]
    if volume is not None:
        inv = np.linalg.inv(affine)
        vox = V @ inv[:3, :3].T + inv[:3, 3]
        rows = np.arange(n)
        frac = vox[rows, keys[:, 3]] - keys[rows, keys[:, 3]]
        _check_against_volume(keys, frac, np.asarray(volume, float), float(iso), inside)
        checks.append("vertices = crossing grid edges, at the linear interpolation")
    edges, edge_tris, tri_edges = _topology(F, n)
    ring = _rings(F, n)
    checks.append("closed, consistently oriented 2-manifold")
    cube = _cubes(keys, F)
    piece, is_tube = _pieces(edges, edge_tris, cube, F, keys, n)
    checks.append("triangles in unit cubes; pieces disks or tubes, 4 per vertex")
    g = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    ncomp, comp_v = connected_components(g, directed=False)
    nv = np.bincount(comp_v, minlength=ncomp)
    ne = np.bincount(comp_v[edges[:, 0]], minlength=ncomp)
    nf = np.bincount(comp_v[F[:, 0]], minlength=ncomp) if len(F) else np.zeros(ncomp, int)
    comp_chi = [int(x) for x in nv - ne + nf]
    edge_index = {(int(u), int(v)): e for e, (u, v) in enumerate(edges.tolist())}
    return Mesh(V, F, affine, keys, key_index, edges, edge_index, edge_tris, tri_edges, ring,
                cube, piece, is_tube, comp_v, comp_chi, checks)


# --------------------------------------------------------------------------------------------
# The surface graph
# --------------------------------------------------------------------------------------------


@dataclass
class Graph:
    mesh: Mesh
    is_edge: np.ndarray      # (E,) bool: the mesh edge is a graph edge
    length_mm: np.ndarray    # (E,) Euclidean length of every mesh edge
    adj: list                # adj[v]: [(neighbour, mesh edge id)] over graph edges
    cache: dict = field(default_factory=dict)

    def edge(self, u, v):
        """Graph edge id joining u and v, or None."""
        e = self.mesh.edge(u, v)
        return e if e is not None and self.is_edge[e] else None


def full_graph(mesh):
    """Every mesh edge as a graph edge (for cycles that are not on the surface graph, such as
    Homology.basis_cycles)."""
    adj = [[] for _ in range(mesh.n)]
    for e, (u, v) in enumerate(mesh.edges.tolist()):
        adj[u].append((v, e))
        adj[v].append((u, e))
    length = np.linalg.norm(mesh.V[mesh.edges[:, 0]] - mesh.V[mesh.edges[:, 1]], axis=1)
    return Graph(mesh, np.ones(len(mesh.edges), bool), length, adj)


def surface_graph(mesh):
    """The graph isotopo measures loops on (module docstring, 4)."""
    t0, t1 = mesh.edge_tris[:, 0], mesh.edge_tris[:, 1]
    boundary = (mesh.cube[t0] != mesh.cube[t1]).any(axis=1)
    in_tube = ~boundary & mesh.piece_is_tube[mesh.piece[t0]]
    is_edge = boundary | in_tube
    adj = [[] for _ in range(mesh.n)]
    for e in np.nonzero(is_edge)[0].tolist():
        u, v = mesh.edges[e]
        adj[u].append((int(v), e))
        adj[v].append((int(u), e))
    length = np.linalg.norm(mesh.V[mesh.edges[:, 0]] - mesh.V[mesh.edges[:, 1]], axis=1)
    return Graph(mesh, is_edge, length, adj)


# --------------------------------------------------------------------------------------------
# Homology
# --------------------------------------------------------------------------------------------


@dataclass
class Homology:
    edge_class: list     # per mesh edge: class vector as an int bitset
    genus: list          # per component
    leftover: list       # the 2g leftover edges (bit k <-> leftover[k])
    tree_parent: list    # primal spanning tree: (parent vertex, edge) or None at roots

    def walk_class(self, mesh, cycle):
        """Class of the closed walk through `cycle`'s vertices (last joined back to first)."""
        c = 0
        for i, u in enumerate(cycle):
            e = mesh.edge(u, cycle[(i + 1) % len(cycle)])
            if e is None:
                _fail(f"vertices {u} and {cycle[(i + 1) % len(cycle)]} are not joined by a mesh edge")
            c ^= self.edge_class[e]
        return c

    def basis_cycles(self, mesh):
        """The fundamental cycle of each leftover edge ab in the primal tree (class e_k): the tree
        path a .. lca .. b, closed by ab. Cycles of mesh edges (use full_graph to measure them)."""
        out = []
        for e in self.leftover:
            a, b = (int(x) for x in mesh.edges[e])
            pa, pb = self._root_path(a), self._root_path(b)
            while len(pa) > 1 and len(pb) > 1 and pa[-2] == pb[-2]:
                pa.pop()
                pb.pop()
            out.append(pa + pb[:-1][::-1])
        return out

    def _root_path(self, v):
        path = [v]
        while self.tree_parent[v] is not None:
            v = self.tree_parent[v][0]
            path.append(v)
        return path


def homology(mesh):
    """Z/2 homology by tree-cotree (module docstring, 5)."""
    n, m, E = mesh.n, len(mesh.F), len(mesh.edges)
    nbrs = [[] for _ in range(n)]
    for e, (u, v) in enumerate(mesh.edges.tolist()):
        nbrs[u].append((v, e))
        nbrs[v].append((u, e))
    in_tree = np.zeros(E, bool)
    parent = [None] * n
    seen = np.zeros(n, bool)
    for r in range(n):
        if seen[r]:
            continue
        seen[r] = True
        queue = deque([r])
        while queue:
            u = queue.popleft()
            for v, e in nbrs[u]:
                if not seen[v]:
                    seen[v] = True
                    in_tree[e] = True
                    parent[v] = (u, e)
                    queue.append(v)

    # Dual tree: triangles joined across edges not in the primal tree.
    in_cotree = np.zeros(E, bool)
    tparent = [-1] * m   # edge to the parent triangle
    order, roots = [], []
    tseen = np.zeros(m, bool)
    tri_edges = mesh.tri_edges.tolist()
    edge_tris = mesh.edge_tris.tolist()
    for r in range(m):
        if tseen[r]:
            continue
        tseen[r] = True
        roots.append(r)
        queue = deque([r])
        while queue:
            t = queue.popleft()
            order.append(t)
            for e in tri_edges[t]:
                if in_tree[e]:
                    continue
                a, b = edge_tris[e]
                o = b if a == t else a
                if not tseen[o]:
                    tseen[o] = True
                    in_cotree[e] = True
                    tparent[o] = e
                    queue.append(o)
    ncomp = len(mesh.comp_chi)
    if len(roots) != ncomp:
        _fail(f"the dual of the cotree has {len(roots)} parts for {ncomp} components")

    leftover = [int(e) for e in np.nonzero(~in_tree & ~in_cotree)[0]]
    cls = [0] * E
    for k, e in enumerate(leftover):
        cls[e] = 1 << k
    # Leaves first: a triangle's edges other than the one to its parent are known by then.
    for t in reversed(order):
        pe = tparent[t]
        if pe < 0:
            a, b, c = tri_edges[t]
            if cls[a] ^ cls[b] ^ cls[c]:
                _fail(f"dual-tree root triangle {t}: its boundary does not sum to 0")
            continue
        x = 0
        for e in tri_edges[t]:
            if e != pe:
                x ^= cls[e]
        cls[pe] = x

    comp_of_edge = mesh.comp_v[mesh.edges[:, 0]]
    left_per_comp = np.bincount(comp_of_edge[leftover], minlength=ncomp) if leftover else np.zeros(ncomp, int)
    genus = []
    for c in range(ncomp):
        if left_per_comp[c] != 2 - mesh.comp_chi[c] or left_per_comp[c] % 2:
            _fail(f"component {c}: {left_per_comp[c]} leftover edges, but 2 - chi = "
                  f"{2 - mesh.comp_chi[c]}")
        genus.append(int(left_per_comp[c]) // 2)
    return Homology(cls, genus, leftover, parent)


# --------------------------------------------------------------------------------------------
# Cycles
# --------------------------------------------------------------------------------------------


@dataclass
class Cycle:
    vertices: list   # simple cycle, last vertex joined back to the first
    edges: int       # length in graph edges
    mm: float        # length along the interpolated vertex positions
    cls: int         # homology class (bitset)

    def points(self, mesh):
        """Midpoints of the vertices' grid edges (isotopo's `points`, voxel coordinates)."""
        return [mesh.midpoint(v) for v in self.vertices]

    def length(self, metric):
        return self.edges if metric == "edges" else self.mm


def make_cycle(graph, hom, vertices):
    """A Cycle from a vertex list; checks it is a simple closed walk of graph edges."""
    vertices = [int(v) for v in vertices]
    if len(set(vertices)) != len(vertices) or len(vertices) < 3:
        _fail(f"not a simple cycle: {vertices}")
    mm = 0.0
    for i, u in enumerate(vertices):
        w = vertices[(i + 1) % len(vertices)]
        e = graph.edge(u, w)
        if e is None:
            why = "a mesh edge inside a disk piece" if graph.mesh.edge(u, w) is not None else "no mesh edge"
            _fail(f"cycle step {u} -> {w} is not a graph edge ({why})")
        mm += float(graph.length_mm[e])
    return Cycle(vertices, len(vertices), mm, hom.walk_class(graph.mesh, vertices))


def _weighted_adj(graph, hom, metric):
    """adj[v] = [(neighbour, weight, class of the edge)] over graph edges (cached per metric)."""
    hit = graph.cache.get(metric)
    if hit is None or hit[0] is not hom:
        cls, lm = hom.edge_class, graph.length_mm
        adj = [[(x, 1 if metric == "edges" else float(lm[e]), cls[e]) for x, e in a]
               for a in graph.adj]
        hit = graph.cache[metric] = (hom, adj)
    return hit[1]


def _path(parent, v):
    path = [v]
    while parent[v] is not None:
        v = parent[v]
        path.append(v)
    return path[::-1]


def gf2_rank(vectors):
    """Rank over Z/2 of int bitsets."""
    basis = {}  # leading bit -> vector
    for c in vectors:
        while c and (c.bit_length() - 1) in basis:
            c ^= basis[c.bit_length() - 1]
        if c:
            basis[c.bit_length() - 1] = c
    return len(basis)


def hitting_set(graph, hom):
    """Vertices that every non-trivial closed walk passes through: those of 2g graph cycles whose
    classes span H1 (per component of positive genus). A non-trivial class pairs oddly with some
    class of a spanning set (the intersection form is non-degenerate), and two cycles of one graph
    that cross oddly share a vertex. The cycles are fundamental cycles of a breadth-first tree of
    the surface graph (it is the 1-skeleton of a decomposition into disks, so they span H1),
    shortest first, kept while their classes are independent."""
    mesh, adj = graph.mesh, _weighted_adj(graph, hom, "edges")
    depth, cls, parent = {}, {}, {}
    for r in range(mesh.n):
        if r in depth or hom.genus[mesh.comp_v[r]] == 0:
            continue
        depth[r], cls[r], parent[r] = 0, 0, None
        queue = deque([r])
        while queue:
            u = queue.popleft()
            for x, _, h in adj[u]:
                if x not in depth:
                    depth[x], cls[x], parent[x] = depth[u] + 1, cls[u] ^ h, u
                    queue.append(x)
    cand = sorted((depth[u] + depth[x], u, x, cls[u] ^ cls[x] ^ h)
                  for u in depth for x, _, h in adj[u] if u < x)
    basis = {}  # leading bit -> reduced vector (Gaussian elimination over Z/2 on int bitsets)
    rank, chosen = 2 * sum(hom.genus), []
    for _, u, x, c in cand:
        if len(basis) == rank:
            break
        while c and (c.bit_length() - 1) in basis:
            c ^= basis[c.bit_length() - 1]
        if c:
            basis[c.bit_length() - 1] = c
            chosen.append((u, x))
    if len(basis) != rank:
        _fail(f"the surface graph's cycles span rank {len(basis)} of H1, not 2g = {rank}")
    hit = set()
    for u, x in chosen:
        # The cycle: u and x up to their lowest common ancestor.
        while u != x:
            if depth[u] < depth[x]:
                u, x = x, u
            hit.add(u)
            u = parent[u]
        hit.add(u)
    return sorted(hit)


def systole(graph, hom, metric="edges"):
    """Shortest non-trivial closed walk of the surface graph (module docstring, 6): a Cycle, or
    None when every component has genus 0."""
    if metric not in METRICS:
        _fail(f"metric must be one of {METRICS}")
    adj = _weighted_adj(graph, hom, metric)
    sources = hitting_set(graph, hom)
    done_source = bytearray(graph.mesh.n)
    eps = 1e-9
    best, best_rec = math.inf, None
    for s in sources:
        limit = best / 2 + eps
        dist, cls, parent = {s: 0}, {s: 0}, {s: None}
        final = []
        heap = [(0, s)]
        while heap:
            d, u = heapq.heappop(heap)
            if d > limit:
                break
            if d > dist[u]:
                continue
            final.append(u)
            for x, w, h in adj[u]:
                nd = d + w
                if done_source[x] or nd > limit or nd >= dist.get(x, math.inf):
                    continue
                dist[x], cls[x], parent[x] = nd, cls[u] ^ h, u
                heapq.heappush(heap, (nd, x))
        fin = set(final)
        for u in final:
            du, cu = dist[u], cls[u]
            for x, w, h in adj[u]:
                if x > u and x in fin:
                    L = du + w + dist[x]
                    if L < best - eps and (cu ^ cls[x] ^ h):
                        best, best_rec = L, (parent, u, x)
        done_source[s] = 1
    if best_rec is None:
        return None
    parent, a, b = best_rec
    pa, pb = _path(parent, a), _path(parent, b)
    return make_cycle(graph, hom, pa + pb[1:][::-1])


# --------------------------------------------------------------------------------------------
# Odd crossings
# --------------------------------------------------------------------------------------------


def crossing_marks(graph, Z):
    """Set of directed pairs (z, x): at vertex z of the simple cycle Z, the graph edge zx is
    strictly on Z's left (module docstring, 7)."""
    k = len(Z)
    if k < 3 or len(set(Z)) != k:
        _fail(f"Z must be a simple cycle, got {Z}")
    marks = set()
    for i, z in enumerate(Z):
        p, q = Z[i - 1], Z[(i + 1) % k]
        if graph.edge(z, p) is None or graph.edge(z, q) is None:
            _fail(f"Z is not a cycle of graph edges at vertex {z}")
        ring = graph.mesh.ring[z]
        j = ring.index(q)
        while True:
            j = (j + 1) % len(ring)
            x = ring[j]
            if x == p:
                break
            if graph.edge(z, x) is not None:
                marks.add((z, x))
    return marks


def walk_parity(marks, walk):
    """Intersection number mod 2 of the closed walk (vertex list) with the cycle of `marks`."""
    par = 0
    for i, u in enumerate(walk):
        v = walk[(i + 1) % len(walk)]
        par ^= ((u, v) in marks) ^ ((v, u) in marks)
    return int(par)


def shortest_odd_cycle(graph, Z, metric="edges", hom=None):
    """Shortest closed walk of the graph crossing the simple cycle Z (vertex list) an odd number of
    times, by the double cover (module docstring, 7): a Cycle, or None if there is none."""
    if metric not in METRICS:
        _fail(f"metric must be one of {METRICS}")
    marks = crossing_marks(graph, Z)
    hom = hom if hom is not None else homology(graph.mesh)
    adj = _weighted_adj(graph, hom, metric)
    eps = 1e-9
    best, best_rec = math.inf, None
    done_source = set()
    for s in Z:
        # States are 2 v + sheet.
        start, goal = 2 * s, 2 * s + 1
        dist, parent = {start: 0}, {start: None}
        heap = [(0, start)]
        while heap:
            d, st = heapq.heappop(heap)
            if d >= best - eps:
                break
            if d > dist[st]:
                continue
            if st == goal:
                best, best_rec = d, (parent, goal)
                break
            u, sheet = st >> 1, st & 1
            for x, w, _ in adj[u]:
                if x in done_source:
                    continue
                odd = ((u, x) in marks) ^ ((x, u) in marks)
                nx, nd = 2 * x + (sheet ^ odd), d + w
                if nd < dist.get(nx, math.inf) and nd < best - eps:
                    dist[nx], parent[nx] = nd, st
                    heapq.heappush(heap, (nd, nx))
        done_source.add(s)
    if best_rec is None:
        return None
    parent, st = best_rec
    walk = [v >> 1 for v in _path(parent, st)][:-1]  # drop the return to s
    c = make_cycle(graph, hom, walk)
    if walk_parity(marks, walk) != 1:
        _fail("internal: the double-cover walk does not cross Z oddly")
    return c


def intersection_matrix(graph, hom, cycles):
    """Pairwise crossing parities of simple cycles (vertex lists) of `graph`."""
    marks = [crossing_marks(graph, z) for z in cycles]
    return np.array([[walk_parity(mz, w) for mz in marks] for w in cycles], dtype=np.int64)


# --------------------------------------------------------------------------------------------
# Checks
# --------------------------------------------------------------------------------------------


@dataclass
class Result:
    ok: bool = True
    failures: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    lines: list = field(default_factory=list)
    data: dict = field(default_factory=dict)

    def fail(self, msg):
        self.ok = False
        self.failures.append(msg)

    def report(self, out=sys.stdout):
        for l in self.lines:
            print(l, file=out)
        for w in self.warnings:
            print("NOTE: " + w, file=out)
        for f in self.failures:
            print("FAIL: " + f, file=out)
        print("OK" if self.ok else f"FAILED ({len(self.failures)} failures)", file=out)


@dataclass
class Surface:
    """Everything the checks need about one isosurface."""
    mesh: Mesh
    graph: Graph
    hom: Homology


def build_surface(vol, iso, conn=6, inside="above", mesh_path=None, check_volume=True):
    data, affine = load_volume(vol)
    # Meshed, unless given, into a folder removed once read (hundreds of runs must not fill /tmp).
    with tempfile.TemporaryDirectory(prefix="oracle_loops_") as tmp:
        ply = mesh_path or mesh_volume(vol, iso, Path(tmp) / "mesh.ply", conn, inside)
        mesh = load_mesh(ply, affine, data if check_volume else None, iso, inside)
    return Surface(mesh, surface_graph(mesh), homology(mesh))


def _polyline_mm(points, affine):
    """World length of the closed polyline through voxel-coordinate points."""
    p = np.asarray(points, float) @ affine[:3, :3].T + affine[:3, 3]
    return float(np.linalg.norm(p - np.roll(p, 1, axis=0), axis=1).sum()) if len(p) else 0.0


def _fmt_points(points, limit=None):
    pts = points if limit is None or len(points) <= limit else points[:limit] + ["..."]
    return " ".join("(" + ",".join(f"{c:g}" for c in p) + ")" if isinstance(p, list) else p for p in pts)


def _loop_vertices(surf, loop, name, res, nontrivial=True):
    """Vertices of a reported loop after the structural checks; None (with failures) if broken."""
    pts = loop.get("points") or []
    try:
        vs = [surf.mesh.vertex_of_point(p) for p in pts]
    except OracleError as e:
        res.fail(f"{name}: {e}")
        return None
    bad = [pts[i] for i, v in enumerate(vs) if v is None]
    if bad:
        res.fail(f"{name}: points not on a mesh vertex (grid edge not crossing): {_fmt_points(bad, 5)}")
        return None
    if loop.get("length") != len(pts):
        res.fail(f"{name}: length {loop.get('length')} but {len(pts)} points")
    try:
        c = make_cycle(surf.graph, surf.hom, vs)
    except OracleError as e:
        res.fail(f"{name}: {e}")
        return None
    if nontrivial and c.cls == 0:
        res.fail(f"{name}: trivial in homology (it separates the surface)")
        return None
    return c


def check_analysis(vol, iso, conn=6, inside="above", analysis=None, mesh_path=None,
                   require_mutual=False, require_systole=False):
    """Checks `isotopo analyze` output (a dict, a JSON path, or None to run it) against the oracle.
    Structural faults of a loop and a genus mismatch always fail; (1) mutual shortest odd
    crossing and (2) min size == systole fail only when required."""
    res = Result()
    surf = build_surface(vol, iso, conn, inside, mesh_path)
    if analysis is None:
        analysis = json.loads(run_isotopo("analyze", vol, *_surface_args(iso, conn, inside), "--json"))
    elif not isinstance(analysis, dict):
        analysis = json.loads(Path(analysis).read_text())
    genus = sum(surf.hom.genus)
    handles = analysis.get("handles", [])
    res.lines.append(f"surface: {surf.mesh.n} vertices, {len(surf.mesh.F)} triangles, "
                     f"{len(surf.mesh.comp_chi)} components, genus {genus}; "
                     f"{int(surf.mesh.piece_is_tube.sum())} tube pieces")
    res.lines.append("mesh facts verified: " + "; ".join(surf.mesh.mesh_checks))
    if analysis.get("genus", genus) != genus or len(handles) != genus:
        res.fail(f"genus: analyze says {analysis.get('genus')} with {len(handles)} handles, the mesh "
                 f"has genus {genus}")
    sys_e = systole(surf.graph, surf.hom, "edges")
    res.data["systole_edges"] = sys_e.edges if sys_e else None
    mutual_bad, sizes, all_loops = [], [], []
    all_loops_mm, sizes_mm = [], []
    res.lines.append("per handle, each loop: edges, mm reported (isotopo: along the points), mm along "
                     "the interpolated vertices, shortest odd crossing of the other loop (edges)")
    res.lines.append("handle  reeb: len mm(rep) mm(oracle) odd-min  cross: len mm(rep) mm(oracle) odd-min  size")
    for h in handles:
        hid = h.get("id")
        loops = {}
        for kind in ("reeb_loop", "cross_loop"):
            if h.get(kind) is not None:
                c = _loop_vertices(surf, h[kind], f"handle {hid} {kind}", res)
                if c is not None:
                    loops[kind] = c
                    all_loops.append(c)
        present = [h[k]["length"] for k in ("reeb_loop", "cross_loop") if h.get(k) is not None]
        if not present:
            res.fail(f"handle {hid}: neither loop")
        elif h.get("size") != min(present):
            res.fail(f"handle {hid}: size {h.get('size')} is not the smaller loop ({min(present)})")
        if present:
            sizes.append(h.get("size"))
        cols = []
        odd = {}
        r, x = loops.get("reeb_loop"), loops.get("cross_loop")
        # A Reeb-cycle handle's Reeb loop is the shortest crossing its cut once (the cut is
        # reported); an intra-ribbon handle's, the shortest crossing its cross loop once.
        cut = None
        if h.get("cut"):
            cut = _loop_vertices(surf, {"points": h["cut"], "length": len(h["cut"])},
                                 f"handle {hid} cut", res, nontrivial=False)
        if r is not None and x is not None:
            par = walk_parity(crossing_marks(surf.graph, x.vertices), r.vertices)
            odd["cross"] = shortest_odd_cycle(surf.graph, r.vertices, "edges", surf.hom)
            odd["reeb"] = shortest_odd_cycle(surf.graph, (cut or x).vertices, "edges", surf.hom)
            # Both loops are non-trivial here, so on an orientable surface each has an odd
            # crossing partner (the intersection form is non-degenerate): neither search is None.
            if par != 1:
                mutual_bad.append(f"handle {hid}: its loops cross an even number of times")
            if odd["cross"].edges != x.edges:
                mutual_bad.append(f"handle {hid}: cross loop {x.edges} edges, shortest odd crossing of "
                                  f"the Reeb loop {odd['cross'].edges}")
            if odd["reeb"].edges != r.edges:
                what = "the cut" if cut else "the cross loop"
                mutual_bad.append(f"handle {hid}: Reeb loop {r.edges} edges, shortest odd crossing of "
                                  f"{what} {odd['reeb'].edges}")
        # The loops shortest in millimetres, when reported: the same, in mm.
        rm, xm = (h.get("reeb_loop_mm"), h.get("cross_loop_mm"))
        if rm is not None and xm is not None:
            rc = _loop_vertices(surf, rm, f"handle {hid} reeb_loop_mm", res)
            xc = _loop_vertices(surf, xm, f"handle {hid} cross_loop_mm", res)
            if rc is not None and xc is not None:
                all_loops_mm.append((rc, xc))
                oc = shortest_odd_cycle(surf.graph, rc.vertices, "mm", surf.hom)
                orr = shortest_odd_cycle(surf.graph, (cut or xc).vertices, "mm", surf.hom)
                for name, got, want in (("cross_loop_mm", xc.mm, oc.mm), ("reeb_loop_mm", rc.mm, orr.mm)):
                    if got > want * (1 + 1e-5) + 1e-5:
                        mutual_bad.append(f"handle {hid}: {name} {got:.4f} mm, the oracle's shortest "
                                          f"{want:.4f} mm")
                sizes_mm.append(min(rc.mm, xc.mm))
        for kind, other in (("reeb_loop", "reeb"), ("cross_loop", "cross")):
            lp, c = h.get(kind), loops.get(kind)
            if c is not None and "length_mm" in lp:
                along = _polyline_mm(lp["points"], surf.mesh.affine)
                if abs(along - lp["length_mm"]) > 2e-3 * max(1.0, along):
                    res.warnings.append(f"handle {hid} {kind}: length_mm {lp['length_mm']} but the "
                                        f"closed polyline through its points is {along:.3f} mm")
            if lp is None:
                cols.append("-")
            else:
                o = odd.get(other)
                cols.append(f"{lp['length']} {lp.get('length_mm', float('nan')):.3f} "
                            f"{c.mm if c else float('nan'):.3f} {o.edges if o else '-'}")
        res.lines.append(f"{hid:>6}  reeb: {cols[0]}  cross: {cols[1]}  {h.get('size')}")
    for m in mutual_bad:
        (res.fail if require_mutual else res.warnings.append)("(1) " + m)
    # Informational: g handles with two loops each should span H1 (rank 2g) if the loops are a
    # basis of handles; a lower rank means some handles' loops are homologous combinations.
    rank = gf2_rank(c.cls for c in all_loops)
    res.lines.append(f"classes of the {len(all_loops)} valid loops span rank {rank} of 2g = {2 * genus}")
    res.data["loop_rank"] = rank
    smin = min(sizes) if sizes else None
    if sys_e is not None:
        res.lines.append(f"systole: {sys_e.edges} edges ({sys_e.mm:.3f} mm along it), e.g. "
                         f"{_fmt_points(sys_e.points(surf.mesh), 12)}")
    else:
        res.lines.append("systole: none (genus 0)")
    res.lines.append(f"smallest handle size reported: {smin}")
    if smin != (sys_e.edges if sys_e else None):
        msg = f"(2) smallest handle size {smin} != systole {sys_e.edges if sys_e else None} edges"
        (res.fail if require_systole else res.warnings.append)(msg)
    if sizes_mm and sys_e is not None:
        sys_m = systole(surf.graph, surf.hom, "mm")
        smin_mm = min(sizes_mm)
        res.lines.append(f"systole in mm: {sys_m.mm:.4f}; smallest handle size in mm: {smin_mm:.4f}")
        if abs(smin_mm - sys_m.mm) > 1e-5 * max(1.0, sys_m.mm):
            msg = f"(2) smallest handle size {smin_mm:.4f} mm != systole {sys_m.mm:.4f} mm"
            (res.fail if require_systole else res.warnings.append)(msg)
    res.data.update(min_size=smin, genus=genus, mutual_mismatches=len(mutual_bad))
    return res


def check_simplified(vol_out, iso, tau, conn=6, inside="above", tau_mm=False, mesh_path=None):
    """After `isotopo simplify --tau T`: the systole of the output's surface graph is >= T (in
    edges, or in mm with tau_mm)."""
    res = Result()
    surf = build_surface(vol_out, iso, conn, inside, mesh_path)
    metric = "mm" if tau_mm else "edges"
    s = systole(surf.graph, surf.hom, metric)
    res.lines.append(f"genus {sum(surf.hom.genus)}; systole ({metric}): "
                     f"{'none' if s is None else round(s.length(metric), 4)}; tau {tau}")
    res.data["systole"] = None if s is None else s.length(metric)
    if s is not None and s.length(metric) < tau - 1e-9:
        res.fail(f"a non-trivial cycle of {s.edges} edges ({s.mm:.3f} mm) is shorter than tau "
                 f"{tau}: {_fmt_points(s.points(surf.mesh))}")
    return res


# --------------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------------


def _cmd_systole(a):
    surf = build_surface(a.vol, a.iso, a.conn, a.inside, a.mesh)
    print(f"{surf.mesh.n} vertices, {len(surf.mesh.F)} triangles, "
          f"{int(surf.graph.is_edge.sum())} graph edges, {int(surf.mesh.piece_is_tube.sum())} tubes")
    for c, (g, chi) in enumerate(zip(surf.hom.genus, surf.mesh.comp_chi)):
        print(f"component {c}: {int((surf.mesh.comp_v == c).sum())} vertices, chi {chi}, genus {g}")
    for metric in METRICS:
        s = systole(surf.graph, surf.hom, metric)
        if s is None:
            print(f"systole ({metric}): none (genus 0)")
        else:
            print(f"systole ({metric}): {s.edges} edges, {s.mm:.4f} mm: {_fmt_points(s.points(surf.mesh))}")
    return 0


def _cmd_check_analysis(a):
    res = check_analysis(a.vol, a.iso, a.conn, a.inside, a.json, a.mesh,
                         a.require_mutual or a.strict, a.require_systole or a.strict)
    res.report()
    return 0 if res.ok else 1


def _cmd_check_simplified(a):
    tau = math.inf if a.tau in ("inf", "infinity") else float(a.tau)
    res = check_simplified(a.vol, a.iso, tau, a.conn, a.inside, a.tau_mm, a.mesh)
    res.report()
    return 0 if res.ok else 1


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)

    def common(p):
        p.add_argument("vol", help="volume (.nii/.nii.gz and other nibabel formats, or .npy)")
        p.add_argument("iso", type=float)
        p.add_argument("--conn", "--connectivity", type=int, choices=(6, 26), default=6)
        p.add_argument("--inside", choices=("above", "below"), default="above")
        p.add_argument("--mesh", help="`isotopo mesh` output of this volume (else it is run)")

    p = sub.add_parser("systole", help="systole (edges and mm), genus per component, the cycles")
    common(p)
    p.set_defaults(fn=_cmd_systole)
    p = sub.add_parser("check-analysis", help="check `isotopo analyze --json` loops")
    common(p)
    p.add_argument("--json", help="analyze output (else `isotopo analyze` is run)")
    p.add_argument("--require-mutual", action="store_true",
                   help="fail unless each loop is a shortest odd crossing of the other")
    p.add_argument("--require-systole", action="store_true",
                   help="fail unless the smallest handle size is the systole")
    p.add_argument("--strict", action="store_true", help="both of the above")
    p.set_defaults(fn=_cmd_check_analysis)
    p = sub.add_parser("check-simplified", help="systole of a simplified volume >= tau")
    common(p)
    p.add_argument("--tau", required=True, help="number or inf")
    p.add_argument("--tau-mm", action="store_true", help="tau in mm instead of edges")
    p.set_defaults(fn=_cmd_check_simplified)
    a = ap.parse_args(argv)
    try:
        return a.fn(a)
    except OracleError as e:
        print(f"FAIL: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
