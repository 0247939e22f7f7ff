//! An independent topology oracle that shares no code with the cube table: it counts the cells
//! of the cubical complex for the Euler characteristic and flood-fills samples for b0 and b2.
//!
//! Connectivity 6: the solid is the complex of all cells whose corners are all inside.
//! Connectivity 26: the outside (in the padded grid) is that complex built from outside samples,
//! and the solid is its complement, so chi(solid) = chi(outside) - 1.

use isotopo::topology::Connectivity;

/// (b0, b1, b2, chi) of the solid given by `inside` (x fastest), padded with outside.
pub fn betti(inside: &[bool], dims: [usize; 3], conn: Connectivity) -> (i64, i64, i64, i64) {
    let [nx, ny, nz] = dims;
    // Padded grid.
    let (px, py, pz) = (nx + 2, ny + 2, nz + 2);
    let at = |x: usize, y: usize, z: usize| -> bool {
        if x == 0 || y == 0 || z == 0 || x > nx || y > ny || z > nz {
            false
        } else {
            inside[((z - 1) * ny + (y - 1)) * nx + (x - 1)]
        }
    };
    let complex_state = conn == Connectivity::Six; // cells built from inside (6) or outside (26)
    let member = |x: usize, y: usize, z: usize| at(x, y, z) == complex_state;
    // Count cells of each dimension whose corners are all members.
    let mut counts = [0i64; 4];
    for z in 0..pz {
        for y in 0..py {
            for x in 0..px {
                for ex in 0..2 {
                    for ey in 0..2 {
                        for ez in 0..2 {
                            if x + ex >= px || y + ey >= py || z + ez >= pz {
                                continue;
                            }
                            let mut all = true;
                            'c: for dx in 0..=ex {
                                for dy in 0..=ey {
                                    for dz in 0..=ez {
                                        if !member(x + dx, y + dy, z + dz) {
                                            all = false;
                                            break 'c;
                                        }
                                    }
                                }
                            }
                            if all {
                                counts[ex + ey + ez] += 1;
                            }
                        }
                    }
                }
            }
        }
    }
    let chi_complex = counts[0] - counts[1] + counts[2] - counts[3];
    let chi = if complex_state {
        chi_complex
    } else {
        chi_complex - 1
    };
    let (inside_adj, outside_adj) = match conn {
        Connectivity::Six => (6, 26),
        Connectivity::TwentySix => (26, 6),
    };
    let b0 = components(&|x, y, z| at(x, y, z), [px, py, pz], inside_adj);
    let b2 = components(&|x, y, z| !at(x, y, z), [px, py, pz], outside_adj) - 1;
    let b1 = b0 + b2 - chi;
    (b0, b1, b2, chi)
}

/// Connected components of the samples where `sel` holds, with 6- or 26-adjacency.
pub fn components(sel: &dyn Fn(usize, usize, usize) -> bool, dims: [usize; 3], adj: u32) -> i64 {
    let [px, py, pz] = dims;
    let idx = |x: usize, y: usize, z: usize| (z * py + y) * px + x;
    let mut seen = vec![false; px * py * pz];
    let mut n = 0;
    let mut stack = Vec::new();
    let offsets: Vec<(i64, i64, i64)> = (-1..=1)
        .flat_map(|a| (-1..=1).flat_map(move |b| (-1..=1).map(move |c| (a, b, c))))
        .filter(|&(a, b, c)| {
            let m = (a != 0) as u32 + (b != 0) as u32 + (c != 0) as u32;
            m > 0 && (adj == 26 || m == 1)
        })
        .collect();
    for z in 0..pz {
        for y in 0..py {
            for x in 0..px {
                if seen[idx(x, y, z)] || !sel(x, y, z) {
                    continue;
                }
                n += 1;
                seen[idx(x, y, z)] = true;
                stack.push((x, y, z));
                while let Some((a, b, c)) = stack.pop() {
                    for &(dx, dy, dz) in &offsets {
                        let (u, v, w) = (a as i64 + dx, b as i64 + dy, c as i64 + dz);
                        if u < 0
                            || v < 0
                            || w < 0
                            || u >= px as i64
                            || v >= py as i64
                            || w >= pz as i64
                        {
                            continue;
                        }
                        let (u, v, w) = (u as usize, v as usize, w as usize);
                        if !seen[idx(u, v, w)] && sel(u, v, w) {
                            seen[idx(u, v, w)] = true;
                            stack.push((u, v, w));
                        }
                    }
                }
            }
        }
    }
    n
}
