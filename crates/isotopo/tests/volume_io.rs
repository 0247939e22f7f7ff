//! Every format reads back what it wrote, bit for bit, with the same geometry; headers written
//! back to their own format are kept.

use isotopo::volume::{
    self, Affine, DType, Endian, Format, InMemoryVolume, ReadOptions, Samples, VolumeInfo,
};
use std::path::Path;

/// A small deterministic generator (splitmix64), so tests need no extra crates.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        z ^ (z >> 31)
    }
}

fn random_slice(rng: &mut Rng, t: DType, n: usize) -> Samples {
    let mut s = Samples::zeros(t, n);
    for i in 0..n {
        let r = rng.next();
        let v = match t {
            DType::U8 => (r % 256) as f64,
            DType::I8 => (r % 256) as f64 - 128.0,
            DType::U16 => (r % 65536) as f64,
            DType::I16 => (r % 65536) as f64 - 32768.0,
            DType::U32 => (r % (1 << 32)) as f64,
            DType::I32 => (r % (1 << 32)) as f64 - 2147483648.0,
            DType::F32 => {
                f32::from_bits((r as u32) & 0x7f7f_ffff | ((r >> 32) as u32 & 0x8000_0000)) as f64
            }
            DType::F64 => (r as f64 / u64::MAX as f64 - 0.5) * 1e6,
        };
        s.set_f64(i, v);
    }
    // Exact bit patterns for floats, including NaN and infinities.
    if let Samples::F32(v) = &mut s {
        v[0] = f32::NAN;
        v[1] = f32::INFINITY;
        v[2] = -0.0;
    }
    if let Samples::F64(v) = &mut s {
        v[0] = f64::NAN;
        v[1] = f64::NEG_INFINITY;
    }
    s
}

fn test_affine() -> Affine {
    // Rotated 30° about z, anisotropic voxels, an origin.
    let (s, c) = (0.5f64, 0.75f64.sqrt());
    Affine::from_parts(
        [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        [0.5, 0.75, 2.0],
        [-10.0, 20.5, 3.25],
    )
}

fn random_volume(t: DType, seed: u64) -> InMemoryVolume {
    let dims = [7, 5, 4];
    let mut rng = Rng(seed);
    let slices = (0..dims[2])
        .map(|_| random_slice(&mut rng, t, dims[0] * dims[1]))
        .collect();
    let mut info = VolumeInfo::synthetic(dims, t);
    info.affine = test_affine();
    InMemoryVolume::new(info, slices)
}

fn bits_equal(a: &Samples, b: &Samples) -> bool {
    match (a, b) {
        (Samples::F32(x), Samples::F32(y)) => {
            x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
        }
        (Samples::F64(x), Samples::F64(y)) => {
            x.iter().zip(y).all(|(p, q)| p.to_bits() == q.to_bits())
        }
        _ => a == b,
    }
}

fn write(vol: &InMemoryVolume, path: &Path) {
    let mut v = vol.clone();
    volume::convert(&mut v, path, &isotopo::progress::NoProgress)
        .unwrap_or_else(|e| panic!("writing {}: {e}", path.display()));
}

fn read(path: &Path, opts: &ReadOptions) -> InMemoryVolume {
    volume::read_all(path, opts).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()))
}

fn assert_same(a: &InMemoryVolume, b: &InMemoryVolume, geometry_tol: Option<f64>, what: &str) {
    assert_eq!(a.info.dims, b.info.dims, "{what}: dims");
    assert_eq!(a.info.dtype, b.info.dtype, "{what}: dtype");
    for z in 0..a.info.nz() {
        assert!(
            bits_equal(&a.slices[z], &b.slices[z]),
            "{what}: slice {z} differs"
        );
    }
    if let Some(tol) = geometry_tol {
        let d = a.info.affine.max_diff(&b.info.affine);
        assert!(
            d <= tol,
            "{what}: affine differs by {d}: {:?} vs {:?}",
            a.info.affine,
            b.info.affine
        );
    }
}

/// Extensions, the types each can store, and how exactly each keeps geometry.
fn formats() -> Vec<(&'static str, Vec<DType>, Option<f64>)> {
    let all = DType::ALL.to_vec();
    let mgh = vec![DType::U8, DType::I16, DType::I32, DType::F32];
    vec![
        ("nii", all.clone(), Some(1e-5)),
        ("nii.gz", all.clone(), Some(1e-5)),
        ("nrrd", all.clone(), Some(1e-12)),
        ("nhdr", all.clone(), Some(1e-12)),
        ("mgh", mgh.clone(), Some(1e-4)),
        ("mgz", mgh, Some(1e-4)),
        ("mha", all.clone(), Some(1e-12)),
        ("mhd", all.clone(), Some(1e-12)),
        ("npy", all.clone(), None),
        ("raw", all.clone(), None),
        ("tif", all, None),
    ]
}

#[test]
fn every_format_round_trips_every_type() {
    let dir = tempfile::tempdir().unwrap();
    for (ext, types, tol) in formats() {
        for (i, &t) in types.iter().enumerate() {
            let vol = random_volume(t, 1000 + i as u64);
            let path = dir.path().join(format!("v_{}.{ext}", t.name()));
            write(&vol, &path);
            let opts = ReadOptions {
                raw_dims: Some(vol.info.dims),
                raw_type: Some(t),
                ..Default::default()
            };
            let back = read(&path, &opts);
            assert_same(&vol, &back, tol, &format!("{ext} {t}"));
            // Written back to its own format, the file is identical (header kept).
            let again = dir.path().join(format!("again_{}.{ext}", t.name()));
            write(&back, &again);
            let back2 = read(&again, &opts);
            assert_same(
                &back,
                &back2,
                Some(0.0).filter(|_| tol.is_some()),
                &format!("{ext} {t} again"),
            );
            if !ext.ends_with("gz") && ext != "nhdr" && ext != "mhd" && ext != "mgz" {
                assert_eq!(
                    std::fs::read(&path).unwrap(),
                    std::fs::read(&again).unwrap(),
                    "{ext} {t}: rewrite differs"
                );
            }
        }
    }
}

#[test]
fn conversions_between_formats_keep_samples_and_geometry() {
    let dir = tempfile::tempdir().unwrap();
    let vol = random_volume(DType::I16, 7);
    let chain = [
        "a.nii.gz", "b.nrrd", "c.mha", "d.mgz", "e.nhdr", "f.mhd", "g.nii",
    ];
    let mut cur = vol.clone();
    for name in chain {
        let p = dir.path().join(name);
        write(&cur, &p);
        let next = read(&p, &ReadOptions::default());
        let tol = if name.contains("mg") || name.contains("nii") {
            1e-4
        } else {
            1e-5
        };
        assert_same(&vol, &next, Some(tol), name);
        cur = next;
    }
}

#[test]
fn big_endian_files_read_correctly() {
    let dir = tempfile::tempdir().unwrap();
    let vol = random_volume(DType::F32, 3);
    // NRRD big-endian, hand-written header.
    let mut bytes = Vec::new();
    for s in &vol.slices {
        s.encode(Endian::Big, &mut bytes);
    }
    let nrrd = dir.path().join("be.nrrd");
    let mut text =
        b"NRRD0004\ntype: float\ndimension: 3\nsizes: 7 5 4\nendian: big\nencoding: raw\n\n"
            .to_vec();
    text.extend_from_slice(&bytes);
    std::fs::write(&nrrd, &text).unwrap();
    let back = read(&nrrd, &ReadOptions::default());
    assert_same(&vol, &back, None, "nrrd big endian");
    // Raw big-endian.
    let raw = dir.path().join("be.bin");
    std::fs::write(&raw, &bytes).unwrap();
    let back = read(
        &raw,
        &ReadOptions {
            raw_dims: Some([7, 5, 4]),
            raw_type: Some(DType::F32),
            raw_endian: Some(Endian::Big),
            ..Default::default()
        },
    );
    assert_same(&vol, &back, None, "raw big endian");
    // Raw big-endian, every type (the samples are read in place, then their bytes swapped).
    for dtype in DType::ALL {
        let vol = random_volume(dtype, 4);
        let mut bytes = Vec::new();
        vol.slices
            .iter()
            .for_each(|s| s.encode(Endian::Big, &mut bytes));
        let raw = dir.path().join(format!("be-{dtype:?}.bin"));
        std::fs::write(&raw, &bytes).unwrap();
        let opts = ReadOptions {
            raw_dims: Some([7, 5, 4]),
            raw_type: Some(dtype),
            raw_endian: Some(Endian::Big),
            ..Default::default()
        };
        assert_same(
            &vol,
            &read(&raw, &opts),
            None,
            &format!("raw big endian {dtype:?}"),
        );
    }
    // MetaImage MSB.
    let mha = dir.path().join("be.mha");
    let mut text = b"ObjectType = Image\nNDims = 3\nBinaryDataByteOrderMSB = True\nDimSize = 7 5 4\nElementType = MET_FLOAT\nElementDataFile = LOCAL\n".to_vec();
    text.extend_from_slice(&bytes);
    std::fs::write(&mha, &text).unwrap();
    let back = read(&mha, &ReadOptions::default());
    assert_same(&vol, &back, None, "mha big endian");
    // And writing back keeps the byte order.
    let out = dir.path().join("be2.mha");
    write(&back, &out);
    let header = String::from_utf8_lossy(&std::fs::read(&out).unwrap()[..200]).to_string();
    assert!(header.contains("BinaryDataByteOrderMSB = True"), "{header}");
    let again = read(&out, &ReadOptions::default());
    assert_same(&vol, &again, None, "mha big endian rewritten");
}

#[test]
fn c_ordered_numpy_reads_as_x_y_z() {
    let dir = tempfile::tempdir().unwrap();
    let vol = random_volume(DType::U16, 11);
    let [nx, ny, nz] = vol.info.dims;
    // C order, shape (nx, ny, nz): element [x][y][z] at ((x·ny + y)·nz + z).
    let mut data = vec![0u16; nx * ny * nz];
    for z in 0..nz {
        for y in 0..ny {
            for x in 0..nx {
                data[(x * ny + y) * nz + z] = vol.get(x, y, z) as u16;
            }
        }
    }
    let mut dict =
        format!("{{'descr': '<u2', 'fortran_order': False, 'shape': ({nx}, {ny}, {nz}), }}");
    while (10 + dict.len() + 1) % 64 != 0 {
        dict.push(' ');
    }
    dict.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(dict.len() as u16).to_le_bytes());
    bytes.extend_from_slice(dict.as_bytes());
    for v in data {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let p = dir.path().join("c.npy");
    std::fs::write(&p, bytes).unwrap();
    let back = read(&p, &ReadOptions::default());
    assert_same(&vol, &back, None, "npy C order");
}

#[test]
fn raw_dims_and_type_come_from_the_file_name() {
    let dir = tempfile::tempdir().unwrap();
    let vol = random_volume(DType::U8, 5);
    let p = dir.path().join("tooth_7x5x4_uint8.raw");
    write(&vol, &p);
    let back = read(&p, &ReadOptions::default());
    assert_same(&vol, &back, None, "raw from name");
}

#[test]
fn format_is_chosen_by_extension() {
    assert_eq!(
        Format::from_path(Path::new("a.nii.gz")).unwrap().0,
        Format::Nifti
    );
    assert_eq!(
        Format::from_path(Path::new("a.MGZ")).unwrap().0,
        Format::Mgh
    );
    assert_eq!(
        Format::from_path(Path::new("dir.x/a.nhdr")).unwrap().0,
        Format::Nrrd
    );
    assert!(Format::from_path(Path::new("a.xyz")).is_none());
    assert!(Format::from_path(Path::new("noext")).is_none());
}

/// Every volume in ../shared/data reads completely, with the dims its README gives.
#[test]
fn shared_real_volumes_read() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if !dir.exists() {
        eprintln!(
            "skipping: {} not found (it sits beside the checkout in CI)",
            dir.display()
        );
        return;
    }
    let expect: &[(&str, [usize; 3], DType)] = &[
        ("cranium-ct.nii.gz", [256, 256, 108], DType::I16),
        ("lidc2-chest-ct.nii.gz", [256, 256, 133], DType::U8),
        ("freesurfer-wm.mgz", [256, 256, 256], DType::U8),
        ("mni2009a-gm.nii.gz", [197, 233, 189], DType::U8),
        ("embryo.nrrd", [256, 256, 256], DType::U8),
        ("tooth_103x94x161_uint8.raw", [103, 94, 161], DType::U8),
        ("buddha-sdf.nii.gz", [172, 405, 172], DType::F32),
    ];
    for (name, dims, t) in expect {
        let v = read(&dir.join(name), &ReadOptions::default());
        assert_eq!(v.info.dims, *dims, "{name}");
        assert_eq!(v.info.dtype, *t, "{name}");
    }
    // FreeSurfer geometry as nibabel gives it.
    let wm = volume::open(&dir.join("freesurfer-wm.mgz"), &ReadOptions::default()).unwrap();
    let want = Affine {
        m: [
            [-1.0, 0.0, 0.0, 128.0],
            [0.0, 0.0, 1.0, -128.0],
            [0.0, -1.0, 0.0, 128.0],
        ],
    };
    assert!(
        wm.info().affine.max_diff(&want) < 1e-3,
        "{:?}",
        wm.info().affine
    );
}
