//! The flags several commands share, defined once: the input (and how to read headerless
//! files), which isosurface, the window of planes, the sweep axis.

use clap::Args;
use isotopo::grid::Axis;
use isotopo::topology::{Connectivity, Inside, SurfaceOptions};
use isotopo::volume::{self, DType, Endian, ReadOptions};
use isotopo::{Error, Result};
use std::path::PathBuf;

#[derive(clap::ValueEnum, Clone, Copy)]
pub(crate) enum AxisArg {
    X,
    Y,
    Z,
}

impl AxisArg {
    pub(crate) fn axis(self) -> Axis {
        match self {
            AxisArg::X => Axis::X,
            AxisArg::Y => Axis::Y,
            AxisArg::Z => Axis::Z,
        }
    }
}

/// How the volume is swept: along which axis, with how much of it in memory.
#[derive(Args, Clone)]
pub(crate) struct SweepArgs {
    /// Sweep direction.
    #[arg(long, value_enum, default_value = "z")]
    pub(crate) axis: AxisArg,
    /// Planes of the volume held in memory at once (as inside bits); the rest wait in a scratch
    /// file (in TMPDIR) and are read back when a long handle needs them. 0: the whole volume.
    /// Default: as many as fit in 16 MiB, the whole volume when it fits.
    #[arg(long, value_name = "N")]
    pub(crate) max_slices: Option<usize>,
}

/// Which isosurface: the isovalue, the inside side and the digital connectivity.
#[derive(Args, Clone)]
pub(crate) struct SurfaceArgs {
    /// Isovalue, in the volume's values (after any NIfTI scl_slope/scl_inter).
    #[arg(long, allow_negative_numbers = true)]
    pub(crate) iso: f64,
    /// Inside is above the isovalue (CT, probability maps) or below it (signed distance fields).
    #[arg(long, value_enum, default_value = "above")]
    pub(crate) inside: InsideArg,
    /// Digital connectivity of the solid: 6 (inside 6-adjacent, outside 26) or 26 (the reverse).
    #[arg(long, default_value = "6", value_parser = parse_connectivity)]
    pub(crate) connectivity: Connectivity,
}

#[derive(clap::ValueEnum, Clone, Copy)]
pub(crate) enum InsideArg {
    Above,
    Below,
}

impl SurfaceArgs {
    pub(crate) fn options(&self) -> Result<SurfaceOptions> {
        if !self.iso.is_finite() {
            return Err(Error::usage("--iso must be a finite number"));
        }
        Ok(SurfaceOptions {
            iso: self.iso,
            inside: match self.inside {
                InsideArg::Above => Inside::Above,
                InsideArg::Below => Inside::Below,
            },
            connectivity: self.connectivity,
        })
    }
}

pub(crate) fn parse_connectivity(s: &str) -> std::result::Result<Connectivity, String> {
    match s {
        "6" => Ok(Connectivity::Six),
        "26" => Ok(Connectivity::TwentySix),
        _ => Err("use 6 or 26".into()),
    }
}

/// How to read the input; the raw options describe headerless files.
#[derive(Args, Clone)]
pub(crate) struct Input {
    /// Input volume: .nii .nii.gz .nrrd .nhdr .mgh .mgz .mha .mhd .npy .tif, or raw.
    pub(crate) file: PathBuf,
    /// Dimensions of a headerless raw file, e.g. 256,256,128.
    #[arg(long, value_name = "NX,NY,NZ", value_parser = parse_dims)]
    pub(crate) raw_dims: Option<[usize; 3]>,
    /// Sample type of a raw file: uint8, int8, uint16, int16, uint32, int32, float32, float64.
    #[arg(long, value_name = "T", value_parser = parse_dtype)]
    pub(crate) raw_type: Option<DType>,
    /// Byte order of a raw file.
    #[arg(long, value_name = "little|big", value_parser = parse_endian)]
    pub(crate) raw_endian: Option<Endian>,
    /// Voxel size in mm for files that carry none (raw, NumPy, TIFF).
    #[arg(long, value_name = "SX,SY,SZ", value_parser = parse_spacing)]
    pub(crate) raw_spacing: Option<[f64; 3]>,
    /// Bytes to skip at the start of a raw file.
    #[arg(long, value_name = "BYTES", default_value_t = 0)]
    pub(crate) raw_offset: u64,
}

impl Input {
    pub(crate) fn options(&self) -> ReadOptions {
        ReadOptions {
            raw_dims: self.raw_dims,
            raw_type: self.raw_type,
            raw_endian: self.raw_endian,
            raw_spacing: self.raw_spacing,
            raw_offset: self.raw_offset,
        }
    }
    pub(crate) fn open(&self) -> Result<Box<dyn volume::SliceReader>> {
        volume::open(&self.file, &self.options())
    }
}

pub(crate) fn parse_dims(s: &str) -> std::result::Result<[usize; 3], String> {
    let v: Vec<usize> = s
        .split([',', 'x', 'X'])
        .map(|t| {
            t.trim()
                .parse::<usize>()
                .map_err(|_| format!("\"{t}\" is not a size"))
        })
        .collect::<std::result::Result<_, _>>()?;
    <[usize; 3]>::try_from(v).map_err(|_| "expected three sizes NX,NY,NZ".to_string())
}

pub(crate) fn parse_spacing(s: &str) -> std::result::Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .map_err(|_| format!("\"{t}\" is not a number"))
        })
        .collect::<std::result::Result<_, _>>()?;
    let a =
        <[f64; 3]>::try_from(v).map_err(|_| "expected three sizes SX,SY,SZ in mm".to_string())?;
    if a.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
        return Err("voxel sizes must be positive".into());
    }
    Ok(a)
}

pub(crate) fn parse_dtype(s: &str) -> std::result::Result<DType, String> {
    DType::parse(s).ok_or_else(|| format!("unknown type \"{s}\"; use uint8, int8, uint16, int16, uint32, int32, float32 or float64"))
}

pub(crate) fn parse_endian(s: &str) -> std::result::Result<Endian, String> {
    match s {
        "little" | "le" => Ok(Endian::Little),
        "big" | "be" => Ok(Endian::Big),
        _ => Err("use little or big".into()),
    }
}
