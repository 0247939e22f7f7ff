#!/usr/bin/env python3
"""Self-tests of scripts/oracle_loops.py on shapes whose answers are known from geometry.

    cd /work/main && cargo build --release && python3 scripts/test_oracle_loops.py

(isotopo is taken from $ISOTOPO, else target/release/isotopo, else /tmp/isotopo-good; only
`isotopo mesh` is used for the assertions.) Exits 1 if any assertion fails. What is asserted:

- mesh facts: every mesh below passes load_mesh's checks (including against its volume), and
  corrupted meshes (a flipped triangle, a missing triangle, a vertex moved off its grid edge, the
  wrong isovalue) are refused;
- a ball: genus 0, no systole; both connectivities;
- solid tori (R = 8, r = 3; upright, tilted, spacing (1, 1, 2) with an offset origin, and the
  negated field with --inside below): genus 1; the systole (edges and mm) winds once round the
  core and not round the axis (a meridian); upright, it is no longer than the shortest planar
  section of the tube, which is itself a graph cycle of the meridian class; its mm length is
  compared with 2 pi r (ratio printed, loosely bounded to 0.9-1.3); the shortest cycle crossing
  the meridian oddly is a longitude (winds once round the axis, not round the core), no longer
  than the inner equator's section; the shortest crossing that longitude oddly is a meridian of
  the systole's length; crossing parities: meridian x longitude = 1, meridian x meridian = 0,
  inner x outer equator = 0; all meridian sections have one Z/2 class, both equators another;
- one-voxel, 1x2 and 2x2 bridges closing a U of 3x3 bars: systole 4, 6 and 8 edges (4 sqrt(1/2)
  mm for the one-voxel bridge), both connectivities;
- a slab with two holes: genus 2, no longer systole than a hole's section;
- small random smoothed-noise volumes (16^3, box blur, threshold at the median), both
  connectivities: the systole in edges and in mm equals a brute force (every simple cycle up to
  that length, non-separating tested by cutting the triangle adjacency graph along the cycle);
  the shortest odd crossing of a cycle equals a brute force over the simple cycles through it;
- everywhere: the crossing parities of the tree-cotree basis cycles form a symmetric, zero-
  diagonal, invertible matrix M over Z/2 (the intersection form), and the parity of any two
  cycles measured by the double cover equals class(a)^T M class(b);
- check_analysis accepts correct loops (also under --strict) and names the fault of a trivial
  loop, a loop with a gap, a point off the surface, a wrong length, a non-shortest cross loop
  (only when required) and a size above the systole (only when required); check_simplified
  passes tau <= systole and fails tau above it, in edges and in mm; the CLI runs.
"""

import heapq
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import nibabel as nib
import numpy as np
from scipy.ndimage import uniform_filter

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import oracle_loops as ol  # noqa: E402

FAILS = []
TMP = Path(tempfile.mkdtemp(prefix="test_oracle_loops_"))


def check(cond, msg):
    print(("  ok   " if cond else "  FAIL ") + msg)
    if not cond:
        FAILS.append(msg)


def pick_isotopo():
    for exe in (os.environ.get("ISOTOPO"), str(HERE.parent / "target" / "release" / "isotopo"),
                "/tmp/isotopo-good"):
        if exe and Path(exe).exists():
            os.environ["ISOTOPO"] = exe
            return exe
    sys.exit("no isotopo binary: run `cargo build --release` first (or set ISOTOPO)")


# ---------------------------------------------------------------------------------- volumes


def save(name, f, affine=np.eye(4)):
    path = TMP / f"{name}.nii.gz"
    nib.save(nib.Nifti1Image(np.asarray(f, np.float32), affine), path)
    return path


def world_grid(shape, affine):
    idx = np.indices(shape).reshape(3, -1).T.astype(float)
    return idx @ affine[:3, :3].T + affine[:3, 3]


def rotation(ax_deg, az_deg):
    a, b = math.radians(ax_deg), math.radians(az_deg)
    rx = np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])
    rz = np.array([[math.cos(b), -math.sin(b), 0], [math.sin(b), math.cos(b), 0], [0, 0, 1]])
    return rz @ rx


def torus_field(shape, affine, center, R, r, rot):
    """r - distance to the core circle (positive inside); the torus's axis is rot's third column."""
    q = (world_grid(shape, affine) - center) @ rot  # torus frame
    rho = np.hypot(q[:, 0], q[:, 1])
    return (r - np.sqrt((rho - R) ** 2 + q[:, 2] ** 2)).reshape(shape)


def u_with_bridge(ny, nz):
    """Two 3x3 bars joined at the bottom and, at the top, by a bridge 1 x ny x nz voxels."""
    v = np.zeros((12, 10, 14), np.float32)
    v[2:5, 3:6, 2:11] = 1
    v[6:9, 3:6, 2:11] = 1
    v[2:9, 3:6, 2:5] = 1
    v[5, 4:4 + ny, 11 - nz:11] = 1
    return v


def surf_of(path, iso, conn, inside="above"):
    return ol.build_surface(path, iso, conn, inside)


# ---------------------------------------------------------------------------------- helpers


def windings(mesh, cycle, center, R, rot):
    """(turns round the torus axis, turns round the core circle) of a cycle of vertices."""
    q = (mesh.V[cycle] - center) @ rot

    def turns(a, b):
        ang = np.arctan2(b, a)
        d = (np.diff(np.append(ang, ang[0])) + math.pi) % (2 * math.pi) - math.pi
        return int(round(d.sum() / (2 * math.pi)))

    return turns(q[:, 0], q[:, 1]), turns(np.hypot(q[:, 0], q[:, 1]) - R, q[:, 2])


def plane_cycle(surf, axis, index, keep):
    """The graph cycle through the vertices on grid edges in the plane (axis = index) whose
    positions satisfy `keep` (the marching-squares contour of a planar section), or None if those
    vertices do not form exactly one cycle."""
    mesh = surf.mesh
    sel = (mesh.keys[:, 3] != axis) & (mesh.keys[:, axis] == index) & keep(mesh.V)
    vs = set(np.nonzero(sel)[0].tolist())
    nb = {v: [x for x, _ in surf.graph.adj[v] if x in vs] for v in vs}
    if len(vs) < 3 or any(len(x) != 2 for x in nb.values()):
        return None
    start = min(vs)
    cyc, prev, cur = [start], start, nb[start][0]
    while cur != start:
        cyc.append(cur)
        prev, cur = cur, (nb[cur][0] if nb[cur][0] != prev else nb[cur][1])
    return cyc if len(cyc) == len(vs) else None


def rank_gf2(M):
    M = [int("".join(str(int(x)) for x in row), 2) if len(row) else 0 for row in M]
    rank = 0
    for bit in reversed(range(max((m.bit_length() for m in M), default=0))):
        piv = next((i for i in range(rank, len(M)) if M[i] >> bit & 1), None)
        if piv is None:
            continue
        M[rank], M[piv] = M[piv], M[rank]
        for i in range(len(M)):
            if i != rank and M[i] >> bit & 1:
                M[i] ^= M[rank]
        rank += 1
    return rank


def check_intersection_form(surf, cycles, label):
    """Basis intersection matrix M is symplectic-invertible; parity(a, b) = cls(a)^T M cls(b)."""
    full = ol.full_graph(surf.mesh)
    basis = surf.hom.basis_cycles(surf.mesh)
    g2 = len(basis)
    M = ol.intersection_matrix(full, surf.hom, basis) if g2 else np.zeros((0, 0), int)
    check((M == M.T).all() and not np.diag(M).any() and rank_gf2(M) == g2,
          f"{label}: intersection form of the {g2} basis cycles is symmetric, zero-diagonal, "
          "invertible over Z/2")
    for k, c in enumerate(basis[:6]):
        if surf.hom.walk_class(surf.mesh, c) != 1 << k:
            check(False, f"{label}: basis cycle {k} has class e_{k}")
            break
    bad = 0
    marks = [ol.crossing_marks(full, z) for z in cycles]
    for i, a in enumerate(cycles):
        ca = surf.hom.walk_class(surf.mesh, a)
        va = np.array([(ca >> k) & 1 for k in range(g2)])
        for j, b in enumerate(cycles):
            cb = surf.hom.walk_class(surf.mesh, b)
            vb = np.array([(cb >> k) & 1 for k in range(g2)])
            want = int(va @ M @ vb) % 2 if g2 else 0
            bad += ol.walk_parity(marks[j], a) != want
    check(bad == 0, f"{label}: double-cover parity = homology pairing on {len(cycles)}^2 pairs")


def check_graph_against_volume(surf, vol, iso, conn, label, inside="above"):
    """The surface graph, rebuilt independently from the samples: on every cube face, marching
    squares (two crossing edges: one segment; four: the segments cut off the corners that are not
    connected across the face, i.e. the inside ones under 6 and the outside ones under 26) gives
    exactly the graph's edges outside tubes; the tubes are exactly the cubes whose corners on the
    connected side are one body-diagonal pair; every tube's graph edges inside it join its two
    boundary loops."""
    data, _ = ol.load_volume(vol)
    pad = np.full(tuple(d + 2 for d in data.shape), np.nan)
    pad[1:-1, 1:-1, 1:-1] = data
    with np.errstate(invalid="ignore"):
        ins = pad > iso if inside == "above" else pad < iso
    key = lambda p, a: (int(p[0]) - 1, int(p[1]) - 1, int(p[2]) - 1, a)
    want = set()
    for b in range(3):
        u, v = [a for a in range(3) if a != b]
        eu, ev = np.eye(3, dtype=int)[u], np.eye(3, dtype=int)[v]
        shape = [d - (1 if a != b else 0) for a, d in enumerate(ins.shape)]
        sl = lambda off: ins[tuple(slice(o, o + n) for o, n in zip(off, shape))]
        c = [sl((0, 0, 0)), sl(tuple(eu)), sl(tuple(eu + ev)), sl(tuple(ev))]
        for p in np.argwhere((c[0] != c[1]) | (c[1] != c[2]) | (c[2] != c[3])):
            corner = [bool(x[tuple(p)]) for x in c]
            # Face edges, and the two edges at each corner (corner order 0, u, u+v, v).
            edges = [key(p, u), key(p + ev, u), key(p, v), key(p + eu, v)]
            at = [(0, 2), (0, 3), (1, 3), (1, 2)]
            cross = [e for e, (i, j) in zip(edges, [(0, 1), (3, 2), (0, 3), (1, 2)])
                     if corner[i] != corner[j]]
            if len(cross) == 2:
                want.add(frozenset(cross))
            else:
                cut_off = (lambda x: x) if conn == 6 else (lambda x: not x)
                for k in range(4):
                    if cut_off(corner[k]):
                        want.add(frozenset(edges[i] for i in at[k]))
    mesh, g = surf.mesh, surf.graph
    t0, t1 = mesh.edge_tris[:, 0], mesh.edge_tris[:, 1]
    seg = (mesh.cube[t0] != mesh.cube[t1]).any(axis=1)
    have = {frozenset((tuple(mesh.keys[a]), tuple(mesh.keys[b]))) for a, b in mesh.edges[seg & g.is_edge]}
    faults = []
    if have != want or not (seg <= g.is_edge).all():
        faults.append(f"segments: {len(have - want)} extra, {len(want - have)} missing")
    if not (np.bincount(mesh.edges[seg].reshape(-1), minlength=mesh.n) == 4).all():
        faults.append("a vertex without exactly 4 face segments")
    tubes = set()
    corners = np.stack([ins[tuple(slice(o[a], o[a] + ins.shape[a] - 1) for a in range(3))]
                        for o in np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T.tolist()])
    side = corners if conn == 26 else ~corners
    offs = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T
    two = side.sum(axis=0) == 2
    for p in np.argwhere(two):
        on = offs[side[(slice(None), *p)]]
        if (np.abs(on[0] - on[1]) == 1).all():
            tubes.add(tuple(int(x) - 1 for x in p))
    tube_pieces = np.nonzero(mesh.piece_is_tube)[0]
    first = {int(mesh.piece[t]): t for t in range(len(mesh.F))}
    have_t = {tuple(int(x) for x in mesh.cube[first[p]]) for p in tube_pieces}
    if have_t != tubes:
        faults.append(f"tube cubes: oracle {len(have_t)}, samples {len(tubes)}")
    ok = True
    for p in tube_pieces:
        tris = np.nonzero(mesh.piece == p)[0]
        inner = {int(e) for t in tris for e in mesh.tri_edges[t] if not seg[e]}
        loops = {}
        for e in {int(e) for t in tris for e in mesh.tri_edges[t] if seg[e]}:
            a, b = mesh.edges[e]
            loops.setdefault(int(a), set()).add(int(b))
            loops.setdefault(int(b), set()).add(int(a))
        comp = {}
        for s0 in loops:
            if s0 not in comp:
                stack, lab = [s0], len(set(comp.values()))
                while stack:
                    x = stack.pop()
                    if x not in comp:
                        comp[x] = lab
                        stack.extend(loops[x])
        ok &= all(g.is_edge[e] and comp[int(mesh.edges[e][0])] != comp[int(mesh.edges[e][1])] for e in inner)
    if not ok:
        faults.append("a tube's inner edge is not a graph edge joining its two loops")
    in_tube = mesh.piece_is_tube[mesh.piece[t0]] & ~seg
    if (g.is_edge & ~seg & ~in_tube).any():
        faults.append(f"{int((g.is_edge & ~seg & ~in_tube).sum())} graph edges inside disk pieces")
    check(not faults, f"{label}: graph = marching-squares segments of the samples ({len(want)}, 4 per "
          f"vertex) + inner edges of the {len(tubes)} tube cubes {faults or ''}")


# ------------------------------------------------------------------------ brute force (cuts)


def separates(mesh, cycle):
    """Does cutting along the cycle's mesh edges disconnect the triangles on its two sides?
    Alternating searches from both sides: stops when they meet or one side runs out."""
    cut = {mesh.edge(u, cycle[(i + 1) % len(cycle)]) for i, u in enumerate(cycle)}
    a, b = (int(t) for t in mesh.edge_tris[next(iter(cut))])
    side = {a: 1, b: 2}
    fronts = {1: [a], 2: [b]}
    tri_edges, edge_tris = mesh.tri_edges, mesh.edge_tris
    while fronts[1] and fronts[2]:
        for s in (1, 2):
            nxt = []
            for t in fronts[s]:
                for e in tri_edges[t]:
                    if e in cut:
                        continue
                    o = int(edge_tris[e][0] if edge_tris[e][1] == t else edge_tris[e][1])
                    if side.get(o) == 3 - s:
                        return False
                    if o not in side:
                        side[o] = s
                        nxt.append(o)
            fronts[s] = nxt
    return True


def simple_cycles(surf, limit, metric, through=None):
    """Every simple cycle of the surface graph of length <= limit (edges or mm). Without
    `through`: each cycle from its smallest vertex (both directions); with: every cycle through
    one of those vertices, from each of them."""
    lm = surf.graph.length_mm
    adj = [[(x, 1 if metric == "edges" else float(lm[e])) for x, e in a] for a in surf.graph.adj]
    eps = 1e-9
    starts = range(surf.mesh.n) if through is None else through
    for s in starts:
        lo = s if through is None else -1
        # Distances to s over allowed vertices, to prune paths that cannot close in time.
        dist = {s: 0.0}
        heap = [(0.0, s)]
        while heap:
            d, u = heapq.heappop(heap)
            if d > dist[u] or d > limit / 2 + 1:
                continue
            for x, w in adj[u]:
                if x >= lo and d + w < dist.get(x, math.inf):
                    dist[x] = d + w
                    heapq.heappush(heap, (d + w, x))
        path, on = [s], {s}
        stack = [(s, 0.0, iter(adj[s]))]
        while stack:
            u, L, it = stack[-1]
            step = next(it, None)
            if step is None:
                stack.pop()
                on.discard(path.pop())
                continue
            x, w = step
            if x == s and len(path) >= 3 and L + w <= limit + eps:
                yield list(path), L + w
            if x in on or x < lo or L + w + dist.get(x, math.inf) > limit + eps:
                continue
            path.append(x)
            on.add(x)
            stack.append((x, L + w, iter(adj[x])))


def brute_systole(surf, limit, metric):
    """Shortest non-separating simple cycle of length <= limit, by enumeration and cutting."""
    best = None
    for cyc, L in simple_cycles(surf, limit, metric):
        if (best is None or L < best - 1e-9) and not separates(surf.mesh, cyc):
            best = L
    return best


def brute_odd(surf, Z, limit, metric):
    marks = ol.crossing_marks(surf.graph, Z)
    best = None
    for cyc, L in simple_cycles(surf, limit, metric, through=Z):
        if (best is None or L < best - 1e-9) and ol.walk_parity(marks, cyc):
            best = L
    return best


# ---------------------------------------------------------------------------------- tests


def test_mesh_facts_refused():
    print("mesh facts: corrupted meshes are refused")
    f = torus_field((24, 24, 24), np.eye(4), np.array([11.3, 11.6, 11.45]), 6, 2.5, np.eye(3))
    vol = save("small_torus", f)
    ply = ol.mesh_volume(vol, 0.0, TMP / "small_torus.ply")
    V, F = ol.read_ply(ply)

    def write(name, V, F):
        p = TMP / f"{name}.ply"
        head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(V)}\nproperty float x\n"
                f"property float y\nproperty float z\nelement face {len(F)}\n"
                "property list uchar int vertex_indices\nend_header\n").encode()
        faces = np.zeros(len(F), np.dtype([("n", "u1"), ("v", "<i4", (3,))]))
        faces["n"], faces["v"] = 3, F
        p.write_bytes(head + np.asarray(V, "<f4").tobytes() + faces.tobytes())
        return p

    flipped = F.copy()
    flipped[5] = flipped[5][::-1]
    moved = V.copy()
    moved[7] += 0.3
    cases = [("flipped triangle", write("flip", V, flipped), None, "directed edge"),
             ("missing triangle", write("miss", V, F[1:]), None, "not closed"),
             ("vertex off its grid edge", write("moved", moved, F), None, "grid edge"),
             ("wrong isovalue", ply, 0.2, "crossing grid edges")]
    data, aff = ol.load_volume(vol)
    for what, p, iso, needle in cases:
        try:
            ol.load_mesh(p, aff, data if iso is not None else None, iso)
            check(False, f"{what}: refused")
        except ol.OracleError as e:
            check(needle in str(e), f"{what}: refused ({str(e)[:70]})")


def test_ball():
    print("ball")
    shape = (21, 21, 21)
    w = world_grid(shape, np.eye(4))
    f = (6.0 - np.linalg.norm(w - [10.2, 10.4, 9.7], axis=1)).reshape(shape)
    vol = save("ball", f)
    for conn in (6, 26):
        s = surf_of(vol, 0.0, conn)
        check(s.hom.genus == [0], f"conn {conn}: one surface of genus 0 (got {s.hom.genus})")
        check(all(ol.systole(s.graph, s.hom, m) is None for m in ol.METRICS),
              f"conn {conn}: no systole in either metric")
    return vol


def test_torus(label, shape, affine, center, rot, field_sign=1, inside="above", sections=False,
               conns=(6,), form=False):
    R, r = 8.0, 3.0
    f = field_sign * torus_field(shape, affine, center, R, r, rot)
    vol = save(label.replace(" ", "_"), f, affine)
    out = {}
    for conn in conns:
        print(f"torus ({label}), conn {conn}")
        t0 = time.perf_counter()
        s = surf_of(vol, 0.0, conn, inside)
        check(s.hom.genus == [1], f"genus 1 (got {s.hom.genus})")
        check_graph_against_volume(s, vol, 0.0, conn, "torus", inside)
        se = ol.systole(s.graph, s.hom, "edges")
        sm = ol.systole(s.graph, s.hom, "mm")
        dt = time.perf_counter() - t0
        wi = lambda c: windings(s.mesh, c.vertices if hasattr(c, "vertices") else c, center, R, rot)
        check(wi(se)[0] == 0 and abs(wi(se)[1]) == 1,
              f"edge systole ({se.edges} edges, {se.mm:.2f} mm) is a meridian (windings {wi(se)})")
        check(wi(sm)[0] == 0 and abs(wi(sm)[1]) == 1,
              f"mm systole ({sm.edges} edges, {sm.mm:.3f} mm) is a meridian (windings {wi(sm)})")
        ratio = sm.mm / (2 * math.pi * r)
        check(0.9 <= ratio <= 1.3, f"mm systole / (2 pi r) = {ratio:.4f} (loose bound 0.9-1.3)")
        check(se.mm >= sm.mm - 1e-9 and sm.edges >= se.edges, "each systole is shortest in its metric")
        lon = ol.shortest_odd_cycle(s.graph, se.vertices, "edges", s.hom)
        check(abs(wi(lon)[0]) == 1 and wi(lon)[1] == 0,
              f"shortest odd crossing of the meridian ({lon.edges} edges) is a longitude "
              f"(windings {wi(lon)})")
        mer = ol.shortest_odd_cycle(s.graph, lon.vertices, "edges", s.hom)
        check(wi(mer)[0] == 0 and abs(wi(mer)[1]) == 1 and mer.edges == se.edges,
              f"shortest odd crossing of that longitude is a meridian of the systole's length "
              f"({mer.edges} edges, windings {wi(mer)})")
        lon_mm = ol.shortest_odd_cycle(s.graph, sm.vertices, "mm", s.hom)
        check(abs(wi(lon_mm)[0]) == 1,
              f"mm: shortest odd crossing of the meridian is a longitude, {lon_mm.mm:.2f} mm = "
              f"{lon_mm.mm / (2 * math.pi * (R - r)):.4f} x 2 pi (R - r)")
        mk = lambda c: ol.crossing_marks(s.graph, c.vertices if hasattr(c, "vertices") else c)
        check(ol.walk_parity(mk(se), lon.vertices) == 1 and ol.walk_parity(mk(lon), se.vertices) == 1,
              "parity meridian x longitude = 1 (both ways)")
        check(ol.walk_parity(mk(se), se.vertices) == 0, "parity meridian x itself = 0")
        cycles = [se.vertices, sm.vertices, lon.vertices, mer.vertices, lon_mm.vertices]
        if sections:
            cycles += section_checks(s, se, lon, center, R, rot, wi, mk)
        if form:
            check_intersection_form(s, cycles, f"torus ({label})")
        print(f"  (oracle on {s.mesh.n} vertices: mesh, homology and both systoles {dt:.2f} s)")
        out[conn] = (s, se, sm)
    return vol, out


def section_checks(s, se, lon, center, R, rot, wi, mk):
    """Upright torus: planar sections are graph cycles with the expected classes and parities."""
    mer_sections = []
    for axis, other in ((0, 1), (1, 0)):
        for idx in range(int(center[axis]) - 2, int(center[axis]) + 3):
            for sign in (1, -1):
                c = plane_cycle(s, axis, idx, lambda V, o=other, g=sign: g * (V[:, o] - center[o]) > 0)
                if c is not None:
                    mer_sections.append(c)
    zc = int(round(center[2]))
    inner = plane_cycle(s, 2, zc, lambda V: np.hypot(*(V[:, :2] - center[:2]).T) < R)
    outer = plane_cycle(s, 2, zc, lambda V: np.hypot(*(V[:, :2] - center[:2]).T) > R)
    check(len(mer_sections) >= 8 and inner is not None and outer is not None,
          f"{len(mer_sections)} meridian sections and both equators are graph cycles")
    lens = [len(c) for c in mer_sections]
    mcls = {s.hom.walk_class(s.mesh, c) for c in mer_sections}
    check(all(wi(c)[0] == 0 and abs(wi(c)[1]) == 1 for c in mer_sections) and len(mcls) == 1
          and 0 not in mcls, "all meridian sections wind once round the core and share one "
          "non-zero class")
    check(se.edges <= min(lens), f"systole {se.edges} edges <= shortest meridian section "
          f"{min(lens)} (sections {sorted(set(lens))}); equal: {se.edges == min(lens)}")
    check(se.cls in mcls, "the systole has the meridian sections' class")
    lcls = {s.hom.walk_class(s.mesh, inner), s.hom.walk_class(s.mesh, outer)}
    check(len(lcls) == 1 and not (lcls & mcls) and 0 not in lcls and lon.cls in lcls,
          "both equators share one class, other than the meridians', as the odd crossing has")
    check(lon.edges <= len(inner), f"odd crossing of the meridian {lon.edges} edges <= inner "
          f"equator {len(inner)}; outer equator {len(outer)}")
    far = max(mer_sections, key=lambda c: np.linalg.norm(s.mesh.V[c].mean(0) - s.mesh.V[se.vertices].mean(0)))
    check(ol.walk_parity(mk(se), far) == 0 and ol.walk_parity(mk(far), se.vertices) == 0,
          "parity systole x a distant meridian section = 0")
    check(ol.walk_parity(mk(inner), outer) == 0 and ol.walk_parity(mk(inner), far) == 1,
          "parity inner x outer equator = 0, equator x meridian section = 1")
    return mer_sections[:4] + [inner, outer]


def test_bridges():
    out = {}
    for (ny, nz), want in (((1, 1), 4), ((1, 2), 6), ((2, 2), 8)):
        vol = save(f"bridge_{ny}x{nz}", u_with_bridge(ny, nz))
        for conn in (6, 26):
            print(f"U closed by a 1x{ny}x{nz} bridge, conn {conn}")
            s = surf_of(vol, 0.5, conn)
            check_graph_against_volume(s, vol, 0.5, conn, f"bridge conn {conn}")
            se = ol.systole(s.graph, s.hom, "edges")
            check(s.hom.genus == [1] and se is not None and se.edges == want,
                  f"genus 1, systole {se.edges if se else None} edges (want {want})")
            b = brute_systole(s, want, "edges")
            check(b == want, f"brute force (cycles <= {want} edges, cut and check): {b}")
            if want == 4:
                sm = ol.systole(s.graph, s.hom, "mm")
                check(abs(sm.mm - 4 * math.sqrt(0.5)) < 1e-5, f"mm systole {sm.mm:.5f} = 4 sqrt(1/2)")
            out[(ny, nz, conn)] = (vol, s, se)
    return out


def test_slab():
    print("slab with two holes, spacing (1, 1, 2), offset origin")
    v = np.zeros((24, 14, 8), np.float32)
    v[2:22, 2:12, 2:5] = 1
    v[6:9, 5:8, :] = 0
    v[14:17, 5:8, :] = 0
    aff = np.diag([1.0, 1.0, 2.0, 1.0])
    aff[:3, 3] = [-3.0, 5.0, 11.0]
    vol = save("slab2", v, aff)
    for conn in (6, 26):
        s = surf_of(vol, 0.5, conn)
        check(s.hom.genus == [2], f"conn {conn}: genus 2 (got {s.hom.genus})")
        se = ol.systole(s.graph, s.hom, "edges")
        hole = plane_cycle(s, 2, 3, lambda V: (V[:, 0] > -3 + 4.5) & (V[:, 0] < -3 + 9.5)
                           & (V[:, 1] > 5 + 3.5) & (V[:, 1] < 5 + 8.5))
        check(hole is not None and s.hom.walk_class(s.mesh, hole) != 0 and se.edges <= len(hole),
              f"conn {conn}: a hole's section is a non-trivial cycle of {len(hole) if hole else None} "
              f"edges >= systole {se.edges}")
        sm = ol.systole(s.graph, s.hom, "mm")
        odd = ol.shortest_odd_cycle(s.graph, se.vertices, "edges", s.hom)
        check_intersection_form(s, [se.vertices, sm.vertices, odd.vertices, hole], f"slab conn {conn}")


def random_volume(seed, n=16):
    rng = np.random.default_rng(seed)
    v = uniform_filter(rng.random((n, n, n)), size=3, mode="nearest")
    return v, float(np.median(v))


def test_random():
    for seed in (11, 12):
        v, iso = random_volume(seed)
        vol = save(f"rand{seed}", v)
        for conn in (6, 26):
            print(f"random 16^3 (seed {seed}), conn {conn}")
            s = surf_of(vol, iso, conn)
            check_graph_against_volume(s, vol, iso, conn, f"seed {seed} conn {conn}")
            se = ol.systole(s.graph, s.hom, "edges")
            sm = ol.systole(s.graph, s.hom, "mm")
            print(f"  genus {sum(s.hom.genus)} over {len(s.hom.genus)} surfaces, "
                  f"{int(s.mesh.piece_is_tube.sum())} tubes; systole {se.edges} edges, {sm.mm:.4f} mm")
            be = brute_systole(s, se.edges, "edges")
            check(be == se.edges, f"edges systole {se.edges} = brute force {be}")
            bm = brute_systole(s, sm.mm, "mm")
            check(bm is not None and abs(bm - sm.mm) < 1e-9, f"mm systole {sm.mm:.6f} = brute force {bm}")
            cycles = [se.vertices, sm.vertices]
            # Shortest odd crossings of a few non-trivial cycles, against enumeration through Z.
            zs = [se.vertices] + [ol.shortest_odd_cycle(s.graph, se.vertices, "edges", s.hom).vertices]
            for Z in zs:
                for metric in ol.METRICS:
                    o = ol.shortest_odd_cycle(s.graph, Z, metric, s.hom)
                    cycles.append(o.vertices)
                    b = brute_odd(s, Z, o.length(metric), metric)
                    check(b is not None and abs(b - o.length(metric)) < 1e-9,
                          f"shortest odd crossing ({metric}) of a {len(Z)}-cycle: "
                          f"{o.length(metric):.4g} = brute force {b}")
            check_intersection_form(s, cycles, f"random seed {seed} conn {conn}")


def loop_json(surf, cyc):
    """A loop as `isotopo analyze --json` writes it (length_mm along the points, as isotopo)."""
    pts = [surf.mesh.midpoint(v) for v in cyc]
    return {"length": len(cyc), "length_mm": ol._polyline_mm(pts, surf.mesh.affine), "points": pts}


def test_checks(torus_vol, torus_surf, ball_vol):
    print("check_analysis / check_simplified on hand-made reports (upright torus)")
    s, se, _ = torus_surf
    lon = ol.shortest_odd_cycle(s.graph, se.vertices, "edges", s.hom)

    def report(reeb, cross, size=None):
        r, x = loop_json(s, reeb), loop_json(s, cross)
        return {"genus": 1, "handles": [{"id": 0, "size": size or min(r["length"], x["length"]),
                                         "reeb_loop": r, "cross_loop": x}]}

    def run(rep, **kw):
        return ol.check_analysis(torus_vol, 0.0, 6, "above", rep, **kw)

    res = run(report(se.vertices, lon.vertices), require_mutual=True, require_systole=True)
    check(res.ok and not res.warnings, f"correct loops pass under --strict ({res.failures + res.warnings})")

    # A trivial loop: the boundary of one disk piece.
    p = int(np.nonzero(~s.mesh.piece_is_tube)[0][0])
    tris = np.nonzero(s.mesh.piece == p)[0]
    bnd = [e for t in tris for e in s.mesh.tri_edges[t]
           if s.mesh.piece[s.mesh.edge_tris[e][0]] != s.mesh.piece[s.mesh.edge_tris[e][1]]]
    ring = plane_ring(s.mesh, bnd)
    bad_len = report(se.vertices, lon.vertices)
    bad_len["handles"][0]["reeb_loop"]["length"] += 1
    off = report(se.vertices, lon.vertices)
    off["handles"][0]["cross_loop"]["points"][0] = [0.0, 0.0, 0.5]
    faults = [
        ("trivial loop", report(ring, lon.vertices), "trivial"),
        ("loop with a gap", report(se.vertices[:3] + se.vertices[5:], lon.vertices), "not a graph edge"),
        ("wrong length", bad_len, "length"),
        ("point off the surface", off, "not on a mesh vertex"),
    ]
    for what, rep, needle in faults:
        res = run(rep)
        check(not res.ok and any(needle in f for f in res.failures),
              f"{what} fails: {res.failures[:1]}")

    outer = plane_cycle(s, 2, int(round(TORUS_UP[0][2])),
                        lambda V: np.hypot(*(V[:, :2] - TORUS_UP[0][:2]).T) > 8)
    rep = report(se.vertices, outer)
    res = run(rep)
    res2 = run(rep, require_mutual=True)
    check(res.ok and any("(1)" in w for w in res.warnings) and not res2.ok,
          "a cross loop longer than the shortest odd crossing: noted, failure only when required")
    secs = [c for c in (plane_cycle(s, 0, i, lambda V: V[:, 1] > TORUS_UP[0][1]) for i in range(17, 23)) if c]
    long_mer = max(secs, key=len)
    check(len(long_mer) > se.edges, f"a meridian section longer than the systole ({len(long_mer)})")
    if len(long_mer) > se.edges:
        rep = report(long_mer, lon.vertices)
        res, res2 = run(rep), run(rep, require_systole=True)
        check(res.ok and any("(2)" in w for w in res.warnings) and not res2.ok,
              f"smallest size {len(long_mer)} above the systole {se.edges}: noted, failure only when required")

    for tau, mm, want in ((se.edges, False, True), (se.edges + 1, False, False), (10.0, True, True),
                          (100.0, True, False)):
        res = ol.check_simplified(torus_vol, 0.0, tau, 6, "above", mm)
        check(res.ok == want and (want or "shorter than tau" in res.failures[0]),
              f"check_simplified tau {tau}{' mm' if mm else ''}: {'passes' if want else 'fails'}")
    check(ol.check_simplified(ball_vol, 0.0, math.inf).ok, "check_simplified tau inf on a ball passes")

    def cli(*args):
        return subprocess.run([sys.executable, str(HERE / "oracle_loops.py"), *map(str, args)],
                              capture_output=True, text=True)

    p = cli("systole", torus_vol, 0)
    check(p.returncode == 0 and f"systole (edges): {se.edges} edges" in p.stdout,
          "CLI `systole` prints the systole")
    good, bad = TMP / "good.json", TMP / "bad.json"
    good.write_text(json.dumps(report(se.vertices, lon.vertices)))
    bad.write_text(json.dumps(bad_len))
    codes = (cli("check-analysis", torus_vol, 0, "--json", good, "--strict").returncode,
             cli("check-analysis", torus_vol, 0, "--json", bad).returncode,
             cli("check-simplified", torus_vol, 0, "--tau", se.edges).returncode,
             cli("check-simplified", torus_vol, 0, "--tau", 100, "--tau-mm").returncode)
    check(codes == (0, 1, 0, 1), f"CLI exit codes: check-analysis good/bad, check-simplified "
          f"pass/fail = {codes} (want (0, 1, 0, 1))")

    # Informational: isotopo's own analysis of this torus (not an assertion on the oracle).
    res = ol.check_analysis(torus_vol, 0.0, 6, "above", None, require_mutual=True, require_systole=True)
    print("  isotopo analyze on the upright torus, --strict: " + ("agrees" if res.ok else f"DISAGREES {res.failures}"))


def plane_ring(mesh, edges):
    """Order the boundary edges of one piece (one loop) into a vertex cycle."""
    nb = {}
    for e in edges:
        u, v = (int(x) for x in mesh.edges[e])
        nb.setdefault(u, []).append(v)
        nb.setdefault(v, []).append(u)
    start = min(nb)
    cyc, prev, cur = [start], start, nb[start][0]
    while cur != start:
        cyc.append(cur)
        prev, cur = cur, (nb[cur][0] if nb[cur][0] != prev else nb[cur][1])
    return cyc


def guarded(test):
    """Runs a test; an exception (e.g. a search finding nothing where it must) is a failure."""
    try:
        test()
    except Exception as e:  # noqa: BLE001 - any crash of the oracle is a failed test
        import traceback
        traceback.print_exc()
        check(False, f"{getattr(test, '__name__', 'test')} raised {type(e).__name__}: {e}")


TORUS_UP = (np.array([19.3, 19.6, 19.45]), np.eye(3))


def main():
    t0 = time.perf_counter()
    print(f"isotopo: {pick_isotopo()}; temporary files in {TMP} (removed if all pass)")
    got = {}
    c, rot = TORUS_UP
    aff = np.diag([1.0, 1.0, 2.0, 1.0])
    aff[:3, 3] = [-5.0, 3.0, 7.0]

    def tori():
        got["up"] = test_torus("upright", (40, 40, 40), np.eye(4), c, rot, sections=True,
                               conns=(6, 26), form=True)
        test_torus("tilted", (40, 40, 40), np.eye(4), c, rotation(30, 20), form=True)
        test_torus("spacing 1,1,2", (40, 40, 22), aff, np.array([14.3, 22.6, 27.45]), rot)
        _, neg = test_torus("negated, inside below", (40, 40, 40), np.eye(4), c, rot, field_sign=-1,
                            inside="below")
        up = got["up"][1][6]
        check(neg[6][1].edges == up[1].edges and abs(neg[6][2].mm - up[2].mm) < 1e-6,
              "negated torus with --inside below: same systoles as the upright torus")

    def checks():
        if "up" not in got or "ball" not in got:
            check(False, "check_analysis tests skipped: the torus or ball test failed")
            return
        test_checks(got["up"][0], got["up"][1][6], got["ball"])

    for test in (test_mesh_facts_refused, lambda: got.update(ball=test_ball()), tori, test_bridges,
                 test_slab, test_random, checks):
        guarded(test)
    print(f"\n{time.perf_counter() - t0:.1f} s; " + (f"{len(FAILS)} FAILED:\n  " + "\n  ".join(FAILS)
                                                    if FAILS else "all passed"))
    if FAILS:
        print(f"temporary files kept in {TMP}")
        return 1
    shutil.rmtree(TMP, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
