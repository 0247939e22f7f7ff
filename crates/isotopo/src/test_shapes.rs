//! Shapes the unit tests share, built from the bits up (no search code).

/// A solid torus about z through the middle of an n³ volume (centre a hundredth of a voxel off
/// the grid, so no sample lies on its surface), radii `big` and `small`.
pub(crate) fn torus(n: usize, big: f64, small: f64) -> crate::grid::MaskVolume {
    let mut v = crate::grid::MaskVolume::new([n, n, n], crate::grid::Frame::identity());
    let c = (n as f64 - 1.0) / 2.0 + 0.01;
    for (x, y, z) in (0..n * n * n).map(|k| (k % n, k / n % n, k / (n * n))) {
        let (dx, dy, dz) = (x as f64 - c, y as f64 - c, z as f64 - c);
        v.set(
            x,
            y,
            z,
            ((dx * dx + dy * dy).sqrt() - big).hypot(dz) < small,
        );
    }
    v
}
