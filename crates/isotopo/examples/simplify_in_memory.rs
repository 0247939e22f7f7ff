//! Simplify a volume held in memory: a ring (a solid torus) with a one-voxel bridge across its
//! hole. The bridge makes a small handle (a loop of 4 edges round it); the ring's own handle is
//! large (its loops are 20 edges and more). `tau = 10` removes the bridge's and keeps the ring's.
//!
//!     cargo run --release --example simplify_in_memory

use isotopo::progress::NoProgress;
use isotopo::volume::InMemoryVolume;
use isotopo::{SimplifyOptions, Source};

fn main() -> isotopo::Result<()> {
    // Samples 1 inside, 0 outside; the isovalue 0.5 lies between.
    let ring = |x: usize, y: usize, z: usize| {
        let (dx, dy, dz) = (x as f64 - 15.5, y as f64 - 15.5, z as f64 - 5.5);
        let rho = (dx.hypot(dy) - 9.0).hypot(dz);
        let bridge = y == 15 && (7..=24).contains(&x) && z == 5;
        rho < 3.5 || bridge
    };
    let volume = InMemoryVolume::from_mask([32, 32, 12], ring);

    let mut opts = SimplifyOptions {
        tau: 10.0,
        ..SimplifyOptions::default()
    };
    opts.surface.iso = 0.5;
    let mut done = isotopo::simplify(Source::from(volume), &opts, &NoProgress)?;

    println!(
        "genus {} -> {}: {} handle(s) removed, {} kept, {} sample(s) changed",
        done.before.b1,
        done.after.b1,
        done.outcome.removed.len(),
        done.outcome.kept.len(),
        done.outcome.edits.len()
    );
    assert_eq!((done.before.b1, done.after.b1), (2, 1));

    // The edited samples, in memory (or `done.write("out.nii.gz", &NoProgress)` for a file).
    let edited = done.edited()?;
    let [x, y, z] = done.outcome.edits[0].0.map(|c| c as usize);
    println!("sample ({x}, {y}, {z}) is now {}", edited.get(x, y, z));
    Ok(())
}
