//! Which parts of the volume the report meshes in full detail: bricks of 16³ cells round the
//! handles shown in 3D, each meshed once however many handles it shows.
//!
//! ```text
//!   brick b along an axis: cells 16b .. 16b+16, samples 16b ..= 16b+16
//!   (one plane of samples shared with the next brick, so their meshes meet)
//!
//!     samples  0 ....... 16 ....... 32 ....... 48
//!     bricks   |    0     |    1     |    2     |
//!   a handle's box ±2 ────────[======]───────▶ bricks 0 and 1
//! ```

use super::scene::Crop;
use super::{HtmlHandle, HtmlOptions};
use std::collections::HashMap;

/// Cells along each side of a brick.
pub(crate) const BRICK: usize = 16;

/// The bricks to mesh, and each handle's bricks (indices into them; `None`: no close-up).
pub(crate) struct Plan {
    pub crops: Vec<Crop>,
    pub bricks_of: Vec<Option<Vec<usize>>>,
}

/// Plans the bricks round each handle, smallest handles first (those tau decides about), while
/// the samples of the bricks stay within `html.max_box_samples`.
pub(crate) fn plan(
    handles: &[HtmlHandle],
    order: &[usize],
    dims: [usize; 3],
    html: &HtmlOptions,
    with_after: bool,
) -> Plan {
    let mut crops = Vec::new();
    let mut index: HashMap<[usize; 3], usize> = HashMap::new();
    let mut bricks_of = vec![None; handles.len()];
    let mut samples = 0;
    if dims.iter().any(|&d| d < 2) {
        return Plan { crops, bricks_of };
    }
    for &i in order {
        let wanted = bricks_round(&handles[i].bbox, dims, html.box_side);
        let new: Vec<&[usize; 3]> = wanted.iter().filter(|b| !index.contains_key(*b)).collect();
        let cost: usize = new
            .iter()
            .map(|b| brick_dims(**b, dims).iter().product::<usize>())
            .sum();
        if samples + cost > html.max_box_samples {
            continue;
        }
        samples += cost;
        let mut mine = Vec::with_capacity(wanted.len());
        for b in wanted {
            let k = *index.entry(b).or_insert_with(|| {
                crops.push(Crop::new(
                    b.map(|v| v * BRICK),
                    brick_dims(b, dims),
                    with_after,
                ));
                crops.len() - 1
            });
            mine.push(k);
        }
        bricks_of[i] = Some(mine);
    }
    Plan { crops, bricks_of }
}

/// Samples of brick `b` along each axis: 17, fewer at the volume's far sides.
fn brick_dims(b: [usize; 3], dims: [usize; 3]) -> [usize; 3] {
    [0, 1, 2].map(|a| (BRICK + 1).min(dims[a] - b[a] * BRICK))
}

/// What a close-up shows beyond a handle's box (voxels): the page clips to the same margin.
pub(crate) const MARGIN: i64 = 4;

/// The bricks covering `bbox` (min x, y, z, max x, y, z) with [`MARGIN`] samples more, at most
/// `side` samples across (its middle where it is larger).
fn bricks_round(bbox: &[i64; 6], dims: [usize; 3], side: usize) -> Vec<[usize; 3]> {
    let mut range = [(0, 0); 3];
    for a in 0..3 {
        // The last brick holds cell dims - 2 (samples dims - 2 and dims - 1).
        let last = (dims[a] - 2) / BRICK;
        let lo = (bbox[a] - MARGIN).clamp(0, dims[a] as i64 - 1) as usize;
        let hi = (bbox[a + 3] + MARGIN).clamp(0, dims[a] as i64 - 1) as usize;
        let (mut lo, mut hi) = (lo.min(hi), lo.max(hi));
        if hi - lo + 1 > side.max(2) {
            let mid = (lo + hi) / 2;
            lo = mid.saturating_sub(side / 2);
            hi = lo + side - 1;
        }
        // Cells lo .. hi - 1, at least one, inside the volume.
        let first = lo.min(dims[a] - 2);
        let end = hi.saturating_sub(1).clamp(first, dims[a] - 2);
        range[a] = ((first / BRICK).min(last), (end / BRICK).min(last));
    }
    let mut out = Vec::new();
    for z in range[2].0..=range[2].1 {
        for y in range[1].0..=range[1].1 {
            for x in range[0].0..=range[0].1 {
                out.push([x, y, z]);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bricks_cover_the_box_inside_the_volume() {
        // Samples 13..=21 along x (box 17..17 with the margin): cells 13..21, bricks 0 and 1.
        let b = bricks_round(&[17, 0, 92, 17, 0, 99], [100, 40, 100], 48);
        let xs: Vec<usize> = b.iter().map(|b| b[0]).collect();
        assert!(xs.contains(&0) && xs.contains(&1) && !xs.contains(&2));
        // Along z, samples 88..=99: the last brick is 6 (cells 96..98).
        assert!(b.iter().all(|b| b[2] == 5 || b[2] == 6));
        assert_eq!(brick_dims([0, 0, 6], [100, 40, 100]), [17, 17, 4]);
        // A box longer than the side shows its middle: at most 48 samples, 4 bricks.
        let long = bricks_round(&[0, 0, 0, 99, 1, 1], [100, 40, 100], 48);
        let xs: std::collections::BTreeSet<usize> = long.iter().map(|b| b[0]).collect();
        assert!(xs.len() <= 4, "{xs:?}");
    }

    #[test]
    fn a_brick_is_shared_and_the_budget_holds() {
        let h = |id: usize, x: i64| HtmlHandle {
            id,
            size: Some(4 + id),
            bbox: [x, 5, 5, x + 1, 6, 6],
            ..HtmlHandle::default()
        };
        let handles = vec![h(0, 5), h(1, 6), h(2, 40)];
        let html = HtmlOptions {
            max_box_samples: 17 * 17 * 17,
            ..HtmlOptions::default()
        };
        let p = plan(&handles, &[0, 1, 2], [64, 64, 64], &html, false);
        assert_eq!(p.crops.len(), 1);
        assert_eq!(p.bricks_of[0], Some(vec![0]));
        assert_eq!(p.bricks_of[1], Some(vec![0]));
        assert_eq!(p.bricks_of[2], None, "beyond the budget");
    }
}
