//! Tests of the systole oracle (`common::systole`) itself: known shapes (ball, tori, bridges, a
//! holed slab) with the values `scripts/oracle_loops.py` reports for the same volumes; a brute
//! force over all short simple cycles, judged by cutting the mesh, on small random volumes; the
//! pruning of the sources; the mesh checks refusing corrupted meshes; and a mutation of the graph
//! (disk-interior edges counted) changing answers, so the graph construction is what is tested.

mod common;

use common::systole::{mesh_of, systole, GraphRule, Metric, Surface, Systole};
use common::{shapes, Rng, BOTH};
use isotopo::topology::Connectivity;
use isotopo::volume::InMemoryVolume;
use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::f64::consts::TAU;
use std::time::Instant;

const EPS: f64 = 1e-9;

// ---------------------------------------------------------------------------------- shapes

/// The U of 3×3 bars of tests/loops.rs, its two arms joined at the top by a row of single voxels.
fn one_voxel_bridge() -> InMemoryVolume {
    InMemoryVolume::from_mask([16, 12, 7], |x, y, z| {
        let bar = (2..=4).contains(&z);
        let u = bar
            && ((2..=4).contains(&y) && (2..=13).contains(&x)
                || (2..=4).contains(&x) && (2..=9).contains(&y)
                || (11..=13).contains(&x) && (2..=9).contains(&y));
        u || z == 3 && y == 9 && (5..=10).contains(&x)
    })
}

/// The U of `scripts/test_oracle_loops.py`: two 3×3 bars joined at the bottom and, at the top, by
/// a bridge of 1 × ny × nz voxels.
fn u_with_bridge(ny: usize, nz: usize) -> InMemoryVolume {
    InMemoryVolume::from_mask([12, 10, 14], |x, y, z| {
        let bars = (3..6).contains(&y) && (2..11).contains(&z);
        let arms = bars && ((2..5).contains(&x) || (6..9).contains(&x));
        let base = (2..9).contains(&x) && (3..6).contains(&y) && (2..5).contains(&z);
        let bridge = x == 5 && (4..4 + ny).contains(&y) && (11 - nz..11).contains(&z);
        arms || base || bridge
    })
}

/// Smoothed noise thresholded at its median (about half the samples inside).
fn random_volume(n: usize, passes: usize, seed: u64) -> (InMemoryVolume, f64) {
    let dims = [n, n, n];
    let v = common::smoothed_noise(dims, passes, &mut Rng(seed));
    (common::volume_from(dims, &v), common::quantile(&v, 0.5))
}

/// Centre of `shapes::field`'s coordinates.
fn field_centre(n: usize) -> f64 {
    (n as f64 - 1.0) / 2.0 + 0.0137
}

// ---------------------------------------------------------------------------------- helpers

/// The edge systole's points are grid edge midpoints (one half-integer coordinate), as many as
/// its edges, consecutive ones on edges of one unit cube.
fn check_cycle_points(s: &Systole, what: &str) {
    assert_eq!(Some(s.cycle.len()), s.edges, "{what}: one point per edge");
    for (i, p) in s.cycle.iter().enumerate() {
        let halves = p
            .iter()
            .filter(|c| (c.fract().abs() - 0.5).abs() < EPS)
            .count();
        let whole = p.iter().filter(|c| c.fract() == 0.0).count();
        assert!(
            halves == 1 && whole == 2,
            "{what}: {p:?} is not a grid edge midpoint"
        );
        let q = s.cycle[(i + 1) % s.cycle.len()];
        assert!(
            (0..3).all(|a| (p[a] - q[a]).abs() <= 1.0) && p != &q,
            "{what}: {p:?} -> {q:?} is not a step within one cube"
        );
    }
}

/// Turns of the closed polyline `pts` round the origin of the plane (a(p), b(p)).
fn turns(pts: &[[f64; 3]], f: impl Fn([f64; 3]) -> (f64, f64)) -> i64 {
    let angle = |p: [f64; 3]| {
        let (a, b) = f(p);
        b.atan2(a)
    };
    let mut total = 0.0;
    for (i, &p) in pts.iter().enumerate() {
        let q = pts[(i + 1) % pts.len()];
        let d = angle(q) - angle(p);
        total += (d + std::f64::consts::PI).rem_euclid(TAU) - std::f64::consts::PI;
    }
    (total / TAU).round() as i64
}

// -------------------------------------------------------------------- brute force (cut and check)

/// What the brute force found among the simple cycles up to its limit.
struct Brute {
    /// Length of the shortest cycle that does not separate its surface.
    shortest_nonseparating: Option<f64>,
    cycles: usize,
}

/// Every simple cycle of the surface graph of length ≤ `limit` (each once), judged separating or
/// not by cutting the mesh along it — independently of the oracle's homology; also asserts, for
/// every cycle, that the oracle's class is non-zero exactly when the cycle does not separate.
fn brute_force(s: &Surface, metric: Metric, limit: f64) -> Brute {
    let mut e = Enumeration {
        s,
        metric,
        limit: limit + EPS,
        start: 0,
        dist: vec![f64::INFINITY; s.vertex_count()],
        on_path: vec![false; s.vertex_count()],
        path: Vec::new(),
        path_edges: Vec::new(),
        cut: Cut::new(s),
        out: Brute {
            shortest_nonseparating: None,
            cycles: 0,
        },
    };
    for start in 0..s.vertex_count() as u32 {
        e.start = start;
        let reached = e.distances_to_start();
        e.path.push(start);
        e.on_path[start as usize] = true;
        e.extend(start, 0.0);
        e.path.clear();
        e.on_path[start as usize] = false;
        for v in reached {
            e.dist[v as usize] = f64::INFINITY;
        }
    }
    e.out
}

struct Enumeration<'a> {
    s: &'a Surface,
    metric: Metric,
    limit: f64,
    /// Cycles are enumerated from their smallest vertex.
    start: u32,
    /// Distance to `start` over vertices ≥ start, within limit / 2 (no vertex of a short enough
    /// cycle is farther), else infinity.
    dist: Vec<f64>,
    on_path: Vec<bool>,
    path: Vec<u32>,
    path_edges: Vec<u32>,
    cut: Cut,
    out: Brute,
}

impl Enumeration<'_> {
    /// Fills `dist` (Dijkstra; non-negative distances order like their bit patterns); returns
    /// the vertices it set.
    fn distances_to_start(&mut self) -> Vec<u32> {
        let mut reached = vec![self.start];
        self.dist[self.start as usize] = 0.0;
        let mut heap = BinaryHeap::from([Reverse((0f64.to_bits(), self.start))]);
        while let Some(Reverse((bits, u))) = heap.pop() {
            let d = f64::from_bits(bits);
            if d > self.dist[u as usize] {
                continue; // stale
            }
            for &(x, e) in self.s.neighbours(u) {
                let nd = d + self.s.length(e, self.metric);
                if x > self.start && nd <= self.limit / 2.0 && nd < self.dist[x as usize] {
                    if self.dist[x as usize] == f64::INFINITY {
                        reached.push(x);
                    }
                    self.dist[x as usize] = nd;
                    heap.push(Reverse((nd.to_bits(), x)));
                }
            }
        }
        reached
    }

    /// Depth-first: every simple path from `start` to `u` of length `len` extended, and closed
    /// back to `start` when short enough.
    fn extend(&mut self, u: u32, len: f64) {
        for &(x, e) in self.s.neighbours(u) {
            let l = len + self.s.length(e, self.metric);
            if x == self.start {
                // Each cycle is met in both directions: keep one.
                if self.path.len() >= 3
                    && l <= self.limit
                    && self.path[1] < *self.path.last().unwrap()
                {
                    self.path_edges.push(e);
                    self.judge(l);
                    self.path_edges.pop();
                }
                continue;
            }
            if x < self.start || self.on_path[x as usize] || l + self.dist[x as usize] > self.limit
            {
                continue;
            }
            self.path.push(x);
            self.path_edges.push(e);
            self.on_path[x as usize] = true;
            self.extend(x, l);
            self.on_path[x as usize] = false;
            self.path_edges.pop();
            self.path.pop();
        }
    }

    fn judge(&mut self, len: f64) {
        self.out.cycles += 1;
        let nonseparating = !self.cut.separates(self.s, &self.path_edges);
        assert_eq!(
            self.s.is_nontrivial(&self.path),
            nonseparating,
            "cycle {:?}: the oracle's class and cutting disagree",
            self.path
        );
        if nonseparating
            && self
                .out
                .shortest_nonseparating
                .is_none_or(|b| len < b - EPS)
        {
            self.out.shortest_nonseparating = Some(len);
        }
    }
}

/// Cutting the triangle adjacency graph along a cycle's mesh edges.
struct Cut {
    is_cut: Vec<bool>,
    side: Vec<u8>,
}

impl Cut {
    fn new(s: &Surface) -> Cut {
        Cut {
            is_cut: vec![false; s.edges.len()],
            side: vec![0; s.triangles.len()],
        }
    }

    /// Whether the triangles of the cycle's component fall apart once the triangle adjacency
    /// across the cycle's edges is removed. Cutting a surface along a simple closed curve leaves
    /// at most two parts, and when it leaves two, the two triangles of each cut edge are in
    /// different parts; so it is enough to grow the parts of the two triangles of one cut edge,
    /// alternately (the smaller side runs out first): they meet iff the component stays
    /// connected.
    fn separates(&mut self, s: &Surface, cycle_edges: &[u32]) -> bool {
        for &e in cycle_edges {
            self.is_cut[e as usize] = true;
        }
        let [a, b] = s.edge_tris[cycle_edges[0] as usize];
        let mut touched = vec![a, b];
        self.side[a as usize] = 1;
        self.side[b as usize] = 2;
        let mut fronts = [vec![a], vec![b]];
        let mut met = false;
        'grow: while !fronts[0].is_empty() && !fronts[1].is_empty() {
            for (k, front) in fronts.iter_mut().enumerate() {
                let mine = k as u8 + 1;
                let mut next = Vec::new();
                for &t in front.iter() {
                    for e in s.tri_edges[t as usize] {
                        if self.is_cut[e as usize] {
                            continue;
                        }
                        let [p, q] = s.edge_tris[e as usize];
                        let o = if p == t { q } else { p };
                        match self.side[o as usize] {
                            0 => {
                                self.side[o as usize] = mine;
                                touched.push(o);
                                next.push(o);
                            }
                            x if x != mine => {
                                met = true;
                                break 'grow;
                            }
                            _ => {}
                        }
                    }
                }
                *front = next;
            }
        }
        for t in touched {
            self.side[t as usize] = 0;
        }
        for &e in cycle_edges {
            self.is_cut[e as usize] = false;
        }
        !met
    }
}

// ---------------------------------------------------------------------------------- tests

#[test]
fn a_ball_has_genus_0_and_no_systole() {
    for conn in BOTH {
        let s = systole(&shapes::ball(21, 6.0), 0.0, conn);
        assert_eq!(s.genus, 0, "conn {}", conn.number());
        assert!(s.edges.is_none() && s.mm.is_none() && s.cycle.is_empty());
    }
}

/// Tori R = 8, r = 3 in a 40³ field: the systole is a meridian, of the length the Python oracle
/// reports for the same volumes (24 edges; 18.7420 and 19.2089 mm), about 2 pi r in mm.
#[test]
fn a_torus_systole_is_a_meridian() {
    let (big_r, r) = (8.0, 3.0);
    // (rotation about x, y, z; edges and mm from `oracle_loops.py systole` on the same volume)
    let cases = [
        ((0.0, 0.0, 0.0), 24, 18.741971056423015),
        ((0.5, 0.3, 0.0), 24, 19.208852274135594),
    ];
    for ((ax, ay, az), want_edges, want_mm) in cases {
        let vol = shapes::torus(40, big_r, r, ax, ay, az);
        let c = field_centre(40);
        for conn in BOTH {
            let what = format!("torus tilted ({ax}, {ay}, {az}), conn {}", conn.number());
            let t = Instant::now();
            let s = systole(&vol, 0.0, conn);
            eprintln!(
                "{what}: {:?} edges, {:?} mm in {:.1?}",
                s.edges,
                s.mm,
                t.elapsed()
            );
            assert_eq!(s.genus, 1, "{what}");
            assert_eq!(s.edges, Some(want_edges), "{what}: as the Python oracle");
            let e = s.edges.unwrap() as f64;
            assert!(4.0 * r <= e && e <= TAU * r * 4.0 / std::f64::consts::PI * 1.1);
            let mm = s.mm.unwrap();
            assert!(
                (mm - want_mm).abs() < 1e-6,
                "{what}: {mm} mm, Python {want_mm}"
            );
            assert!(
                (0.9..1.1).contains(&(mm / (TAU * r))),
                "{what}: {mm} mm vs 2 pi r"
            );
            check_cycle_points(&s, &what);
            // In the torus's own frame: once round the core circle, not round the axis.
            let frame: Vec<[f64; 3]> = s
                .cycle
                .iter()
                .map(|p| shapes::rotate([p[0] - c, p[1] - c, p[2] - c], ax, ay, az))
                .collect();
            let core = turns(&frame, |q| (q[0].hypot(q[1]) - big_r, q[2]));
            let axis = turns(&frame, |q| (q[0], q[1]));
            assert!(core.abs() == 1 && axis == 0, "{what}: turns {core}, {axis}");
        }
    }
}

/// A one-voxel bridge: the loop round it, 4 edges of 1/sqrt 2 mm; 1×2 and 2×2 bridges: 6 and 8.
#[test]
fn bridges_have_systoles_4_6_8() {
    let cases = [
        ("one-voxel bridge (tests/loops.rs)", one_voxel_bridge(), 4),
        ("1x1 bridge", u_with_bridge(1, 1), 4),
        ("1x2 bridge", u_with_bridge(1, 2), 6),
        ("2x2 bridge", u_with_bridge(2, 2), 8),
    ];
    for (name, vol, want) in cases {
        for conn in BOTH {
            let what = format!("{name}, conn {}", conn.number());
            let s = systole(&vol, 0.5, conn);
            assert_eq!((s.genus, s.edges), (1, Some(want)), "{what}");
            check_cycle_points(&s, &what);
            if want == 4 {
                let mm = s.mm.unwrap();
                assert!((mm - 4.0 * 0.5f64.sqrt()).abs() < 1e-6, "{what}: {mm} mm");
            }
        }
    }
}

/// A slab with two holes: genus 2; systole as the Python oracle (14 edges, 12.8284 mm).
#[test]
fn a_two_holed_slab_has_genus_2() {
    for conn in BOTH {
        let s = systole(&shapes::holed_slab(2), 0.0, conn);
        assert_eq!((s.genus, s.edges), (2, Some(14)), "conn {}", conn.number());
        assert!((s.mm.unwrap() - 12.828427124746192).abs() < 1e-6);
        check_cycle_points(&s, "slab");
    }
}

/// Small random volumes (10³–12³, smoothed 2 or 3 times, both connectivities): the shortest
/// non-separating simple cycle found by enumerating every simple cycle up to the oracle's length
/// and cutting the mesh along it is exactly the oracle's (so none is shorter), in edges and in mm;
/// and for every cycle enumerated, the oracle's class is non-zero exactly when the cycle does not
/// separate.
#[test]
fn agrees_with_brute_force_on_small_random_volumes() {
    let (mut with_handles, mut longest, mut cycles) = (0, 0, 0);
    for k in 0..10u64 {
        let (n, passes) = (10 + (k % 3) as usize, 2 + (k % 2) as usize);
        let (vol, iso) = random_volume(n, passes, 7000 + k);
        for conn in BOTH {
            let what = format!(
                "{n}³ passes {passes} seed {}, conn {}",
                7000 + k,
                conn.number()
            );
            let surf = Surface::new(&vol, iso, conn, GraphRule::Exact);
            let s = surf.systole();
            match s.edges {
                None => {
                    // Genus 0: no cycle up to 8 edges may be non-separating.
                    let b = brute_force(&surf, Metric::Edges, 8.0);
                    assert_eq!(b.shortest_nonseparating, None, "{what}");
                    cycles += b.cycles;
                }
                Some(edges) => {
                    with_handles += 1;
                    longest = longest.max(edges);
                    let b = brute_force(&surf, Metric::Edges, edges as f64);
                    assert_eq!(
                        b.shortest_nonseparating,
                        Some(edges as f64),
                        "{what}: edges"
                    );
                    cycles += b.cycles;
                    let mm = s.mm.unwrap();
                    let b = brute_force(&surf, Metric::Mm, mm);
                    let got = b
                        .shortest_nonseparating
                        .expect("a cycle of the oracle's length");
                    assert!(
                        (got - mm).abs() < 1e-9,
                        "{what}: mm {mm}, brute force {got}"
                    );
                    cycles += b.cycles;
                }
            }
        }
    }
    eprintln!(
        "{with_handles}/20 with handles, systoles up to {longest} edges, {cycles} cycles cut"
    );
    assert!(
        with_handles >= 12 && longest >= 6,
        "the cases should exercise the search"
    );
}

/// Pruning (a) is exact: searching from every vertex gives the same systoles as from the hitting
/// set, which is much smaller.
#[test]
fn sources_from_the_hitting_set_suffice() {
    for seed in 0..6 {
        let (vol, iso) = random_volume(16, 1 + seed as usize % 3, 500 + seed);
        for conn in BOTH {
            let surf = Surface::new(&vol, iso, conn, GraphRule::Exact);
            let hit = surf.hitting_set();
            let all: Vec<u32> = (0..surf.vertex_count() as u32).collect();
            assert!(hit.len() < all.len() || surf.total_genus() == 0);
            for metric in [Metric::Edges, Metric::Mm] {
                let a = surf.shortest_nontrivial(metric, &hit).map(|c| c.0);
                let b = surf.shortest_nontrivial(metric, &all).map(|c| c.0);
                assert!(
                    a.is_none() && b.is_none() || (a.unwrap() - b.unwrap()).abs() < EPS,
                    "seed {seed} conn {} {metric:?}: hitting set {a:?}, all {b:?}",
                    conn.number()
                );
                // Every non-trivial cycle found meets the hitting set, the minimal one too.
                if let Some((_, cyc)) = surf.shortest_nontrivial(metric, &all) {
                    assert!(surf.is_nontrivial(&cyc));
                    assert!(cyc.iter().any(|v| hit.binary_search(v).is_ok()));
                }
            }
        }
    }
}

/// The mesh checks refuse corrupted meshes and a wrong isovalue (so they can fail).
#[test]
fn corrupted_meshes_are_refused() {
    let vol = shapes::torus(24, 6.0, 2.5, 0.0, 0.0, 0.0);
    let mesh = mesh_of(&vol, 0.0, Connectivity::Six);
    let mut flipped = mesh.clone();
    flipped.triangles[5].swap(1, 2);
    let mut missing = mesh.clone();
    missing.triangles.remove(0);
    let mut moved = mesh.clone();
    moved.vertices[7][0] += 0.3;
    let cases = [
        ("flipped triangle", flipped, 0.0, "same direction"),
        (
            "missing triangle",
            missing,
            0.0,
            "not in exactly two triangles",
        ),
        ("vertex off its grid edge", moved, 0.0, "grid edge"),
        ("wrong isovalue", mesh.clone(), 0.2, "crossing"),
    ];
    for (what, m, iso, needle) in cases {
        match Surface::from_mesh(m, &vol, iso, GraphRule::Exact) {
            Ok(_) => panic!("{what}: accepted"),
            Err(e) => assert!(e.contains(needle), "{what}: refused with {e:?}"),
        }
    }
    // The intact mesh passes.
    let s = Surface::from_mesh(mesh, &vol, 0.0, GraphRule::Exact).expect("intact mesh");
    assert_eq!(s.total_genus(), 1);
}

/// Counting the edges inside disk pieces as graph edges (a wrong graph) gives shorter "systoles":
/// 18 instead of 24 edges round the tori, and shorter ones on some random volumes; never longer
/// (it is a supergraph). So the tests above do check the graph construction. (The bridges keep 4:
/// no diagonal shortens the loop round a square bar.)
#[test]
fn counting_disk_interior_edges_changes_answers() {
    for conn in BOTH {
        for (ax, ay) in [(0.0, 0.0), (0.5, 0.3)] {
            let vol = shapes::torus(40, 8.0, 3.0, ax, ay, 0.0);
            let exact = Surface::new(&vol, 0.0, conn, GraphRule::Exact).systole();
            let wrong = Surface::new(&vol, 0.0, conn, GraphRule::WithDiskInterior).systole();
            assert_eq!(exact.edges, Some(24));
            assert!(
                wrong.edges.unwrap() < 24,
                "mutated torus: {:?}",
                wrong.edges
            );
        }
        let mut shorter = 0;
        for seed in 0..8 {
            let (vol, iso) = random_volume(12, 3, seed);
            let exact = Surface::new(&vol, iso, conn, GraphRule::Exact).systole();
            let wrong = Surface::new(&vol, iso, conn, GraphRule::WithDiskInterior).systole();
            assert_eq!(exact.genus, wrong.genus);
            if let (Some(a), Some(b)) = (exact.edges, wrong.edges) {
                assert!(b <= a && wrong.mm.unwrap() <= exact.mm.unwrap() + EPS);
                shorter += (b < a) as usize;
            }
        }
        assert!(
            shorter > 0,
            "conn {}: no random answer changed",
            conn.number()
        );
    }
}

/// Fast enough for hundreds of random volumes: 16³ random volumes and a 40³ torus, mesh and both
/// systoles, well under a second each (typically ~10 ms in release).
#[test]
fn is_fast_enough() {
    let t = Instant::now();
    let count = 20;
    for seed in 0..count {
        let (vol, iso) = random_volume(16, 1 + seed as usize % 2, 900 + seed);
        let s = systole(&vol, iso, BOTH[seed as usize % 2]);
        assert!(s.genus > 0);
    }
    let per_volume = t.elapsed().as_secs_f64() / count as f64;
    let t = Instant::now();
    systole(
        &shapes::torus(40, 8.0, 3.0, 0.0, 0.0, 0.0),
        0.0,
        Connectivity::Six,
    );
    let torus = t.elapsed().as_secs_f64();
    eprintln!(
        "16³ random: {:.1} ms per volume; 40³ torus: {:.1} ms",
        1e3 * per_volume,
        1e3 * torus
    );
    assert!(per_volume < 0.25 && torus < 0.5, "too slow");
}
