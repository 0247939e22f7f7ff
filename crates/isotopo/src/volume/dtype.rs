//! Sample types and typed sample buffers.

use std::fmt;

/// The sample types isotopo reads and writes, in every format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DType {
    /// Unsigned 8-bit integers (`uint8`).
    U8,
    /// Signed 8-bit integers (`int8`).
    I8,
    /// Unsigned 16-bit integers (`uint16`).
    U16,
    /// Signed 16-bit integers (`int16`).
    I16,
    /// Unsigned 32-bit integers (`uint32`).
    U32,
    /// Signed 32-bit integers (`int32`).
    I32,
    /// IEEE 754 single-precision floats (`float32`).
    F32,
    /// IEEE 754 double-precision floats (`float64`).
    F64,
}

/// Byte order of samples in a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Endian {
    /// Little-endian: least significant byte first.
    Little,
    /// Big-endian: most significant byte first.
    Big,
}

impl Endian {
    /// The byte order of the machine running isotopo.
    pub const NATIVE: Endian = if cfg!(target_endian = "big") {
        Endian::Big
    } else {
        Endian::Little
    };
}

impl DType {
    /// Every sample type, in declaration order (`U8` to `F64`).
    pub const ALL: [DType; 8] = [
        DType::U8,
        DType::I8,
        DType::U16,
        DType::I16,
        DType::U32,
        DType::I32,
        DType::F32,
        DType::F64,
    ];

    /// Bytes per sample.
    pub fn size(self) -> usize {
        match self {
            DType::U8 | DType::I8 => 1,
            DType::U16 | DType::I16 => 2,
            DType::U32 | DType::I32 | DType::F32 => 4,
            DType::F64 => 8,
        }
    }

    /// The name used on the command line and in messages (`uint8`, `int16`, `float32`, …).
    pub fn name(self) -> &'static str {
        match self {
            DType::U8 => "uint8",
            DType::I8 => "int8",
            DType::U16 => "uint16",
            DType::I16 => "int16",
            DType::U32 => "uint32",
            DType::I32 => "int32",
            DType::F32 => "float32",
            DType::F64 => "float64",
        }
    }

    /// Parses a type name as users write it (`uint8`, `u8`, `uchar`, `int16`, `short`, `float`, …).
    pub fn parse(s: &str) -> Option<DType> {
        let t = match s.trim().to_ascii_lowercase().as_str() {
            "uint8" | "u8" | "uchar" | "ubyte" => DType::U8,
            "int8" | "i8" | "char" | "byte" | "schar" => DType::I8,
            "uint16" | "u16" | "ushort" => DType::U16,
            "int16" | "i16" | "short" => DType::I16,
            "uint32" | "u32" | "uint" => DType::U32,
            "int32" | "i32" | "int" => DType::I32,
            "float32" | "f32" | "float" | "single" => DType::F32,
            "float64" | "f64" | "double" => DType::F64,
            _ => return None,
        };
        Some(t)
    }

    /// True for the floating-point types [`DType::F32`] and [`DType::F64`].
    pub fn is_float(self) -> bool {
        matches!(self, DType::F32 | DType::F64)
    }

    /// Smallest and largest representable value.
    pub fn range(self) -> (f64, f64) {
        match self {
            DType::U8 => (0.0, u8::MAX as f64),
            DType::I8 => (i8::MIN as f64, i8::MAX as f64),
            DType::U16 => (0.0, u16::MAX as f64),
            DType::I16 => (i16::MIN as f64, i16::MAX as f64),
            DType::U32 => (0.0, u32::MAX as f64),
            DType::I32 => (i32::MIN as f64, i32::MAX as f64),
            DType::F32 => (f32::MIN as f64, f32::MAX as f64),
            DType::F64 => (f64::MIN, f64::MAX),
        }
    }
}

impl fmt::Display for DType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A run of samples of one type: one z-slice, usually, in x-fastest order.
#[derive(Clone, Debug, PartialEq)]
pub enum Samples {
    /// Unsigned 8-bit samples.
    U8(Vec<u8>),
    /// Signed 8-bit samples.
    I8(Vec<i8>),
    /// Unsigned 16-bit samples.
    U16(Vec<u16>),
    /// Signed 16-bit samples.
    I16(Vec<i16>),
    /// Unsigned 32-bit samples.
    U32(Vec<u32>),
    /// Signed 32-bit samples.
    I32(Vec<i32>),
    /// Single-precision float samples.
    F32(Vec<f32>),
    /// Double-precision float samples.
    F64(Vec<f64>),
}

/// Runs `$body` with `$v` bound to the typed vector inside a [`Samples`].
#[macro_export]
macro_rules! with_samples {
    ($s:expr, $v:ident => $body:expr) => {
        match $s {
            $crate::volume::Samples::U8($v) => $body,
            $crate::volume::Samples::I8($v) => $body,
            $crate::volume::Samples::U16($v) => $body,
            $crate::volume::Samples::I16($v) => $body,
            $crate::volume::Samples::U32($v) => $body,
            $crate::volume::Samples::I32($v) => $body,
            $crate::volume::Samples::F32($v) => $body,
            $crate::volume::Samples::F64($v) => $body,
        }
    };
}

/// Runs `$body` with `$t` naming the primitive type of the [`DType`] `$dtype` (one copy of
/// `$body` per type: generic code over [`Sample`] called with the samples' own type).
macro_rules! with_dtype {
    ($dtype:expr, $t:ident => $body:expr) => {
        $crate::volume::with_dtype!(@arms $dtype, $t, $body;
            U8 u8, I8 i8, U16 u16, I16 i16, U32 u32, I32 i32, F32 f32, F64 f64)
    };
    (@arms $dtype:expr, $t:ident, $body:expr; $($variant:ident $prim:ty),*) => {
        match $dtype {
            $($crate::volume::DType::$variant => {
                type $t = $prim;
                $body
            })*
        }
    };
}
pub(crate) use with_dtype;

/// A primitive sample type: conversion from file bytes and to `f64`.
pub trait Sample: bytemuck::Pod + Send + Sync + PartialOrd + 'static {
    /// The [`DType`] of this primitive type.
    const DTYPE: DType;
    /// Decodes one sample from exactly `size_of::<Self>()` little-endian bytes (panics otherwise).
    fn from_le(bytes: &[u8]) -> Self;
    /// Decodes one sample from exactly `size_of::<Self>()` big-endian bytes (panics otherwise).
    fn from_be(bytes: &[u8]) -> Self;
    /// The sample with its bytes in the other order.
    fn swap_bytes(self) -> Self;
    /// Appends the sample's little-endian bytes to `out`.
    fn write_le(self, out: &mut Vec<u8>);
    /// Appends the sample's big-endian bytes to `out`.
    fn write_be(self, out: &mut Vec<u8>);
    /// The sample's value as `f64` (exact for every sample type).
    fn to_f64(self) -> f64;
    /// Converts an `f64` that is known to be representable (used for written wall values).
    fn from_f64(v: f64) -> Self;
    /// The typed samples inside a [`Samples`] of this type.
    fn view(s: &Samples) -> Option<&[Self]>;
    /// The test `v > iso` as a comparison in this type (exact: no sample is misclassified).
    fn above(iso: f64) -> Threshold<Self>;
    /// The test `v < iso` as a comparison in this type.
    fn below(iso: f64) -> Threshold<Self>;
}

/// A comparison against the isovalue, done in the samples' own type so that it vectorizes.
#[derive(Clone, Copy, Debug)]
pub enum Threshold<T> {
    /// Every sample passes (the isovalue is below the type's range).
    All,
    /// No sample passes.
    Nothing,
    /// `v > t`.
    Greater(T),
    /// `v < t`.
    Less(T),
}

impl<T: Sample> Threshold<T> {
    /// Whether sample `v` passes the comparison.
    #[inline]
    pub fn test(&self, v: T) -> bool {
        match *self {
            Threshold::All => true,
            Threshold::Nothing => false,
            Threshold::Greater(t) => v > t,
            Threshold::Less(t) => v < t,
        }
    }
}

macro_rules! impl_sample {
    ($t:ty, $d:expr, $variant:ident, int) => {
        impl_sample!(@common $t, $d, $variant);
        impl_sample!(@int $t);
    };
    ($t:ty, $d:expr, $variant:ident, float) => {
        impl_sample!(@common $t, $d, $variant);
        impl_sample!(@float $t);
    };
    (@int $t:ty) => {
        impl IntThreshold for $t {
            // For an integer v: v > iso exactly when v > floor(iso); v < iso when v < ceil(iso).
            fn above_int(iso: f64) -> Threshold<$t> {
                let f = iso.floor();
                if f < <$t>::MIN as f64 { Threshold::All } else if f >= <$t>::MAX as f64 { Threshold::Nothing } else { Threshold::Greater(f as $t) }
            }
            fn below_int(iso: f64) -> Threshold<$t> {
                let c = iso.ceil();
                if c > <$t>::MAX as f64 { Threshold::All } else if c <= <$t>::MIN as f64 { Threshold::Nothing } else { Threshold::Less(c as $t) }
            }
        }
    };
    (@float $t:ty) => {};
    (@common $t:ty, $d:expr, $variant:ident) => {
        impl Sample for $t {
            const DTYPE: DType = $d;
            #[inline]
            fn from_le(b: &[u8]) -> Self {
                <$t>::from_le_bytes(b.try_into().unwrap())
            }
            #[inline]
            fn from_be(b: &[u8]) -> Self {
                <$t>::from_be_bytes(b.try_into().unwrap())
            }
            #[inline]
            fn swap_bytes(self) -> Self {
                <$t>::from_ne_bytes({
                    let mut b = self.to_ne_bytes();
                    b.reverse();
                    b
                })
            }
            #[inline]
            fn write_le(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_le_bytes())
            }
            #[inline]
            fn write_be(self, out: &mut Vec<u8>) {
                out.extend_from_slice(&self.to_be_bytes())
            }
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            fn view(s: &Samples) -> Option<&[Self]> {
                match s {
                    Samples::$variant(v) => Some(v),
                    _ => None,
                }
            }
            fn above(iso: f64) -> Threshold<Self> {
                threshold_above::<$t>(iso)
            }
            fn below(iso: f64) -> Threshold<Self> {
                threshold_below::<$t>(iso)
            }
        }
    };
}

/// Exact integer thresholds.
trait IntThreshold: Sized {
    fn above_int(iso: f64) -> Threshold<Self>;
    fn below_int(iso: f64) -> Threshold<Self>;
}

/// Dispatches to the integer or float rule.
trait ThresholdRule: Sized {
    fn rule_above(iso: f64) -> Threshold<Self>;
    fn rule_below(iso: f64) -> Threshold<Self>;
}

impl<T: IntThreshold> ThresholdRule for T {
    fn rule_above(iso: f64) -> Threshold<T> {
        T::above_int(iso)
    }
    fn rule_below(iso: f64) -> Threshold<T> {
        T::below_int(iso)
    }
}

// For floats the threshold is the isovalue rounded toward the passing side: v > iso for an f32 v
// exactly when v > (the largest f32 not above iso).
impl ThresholdRule for f32 {
    fn rule_above(iso: f64) -> Threshold<f32> {
        let mut t = iso as f32;
        if t as f64 > iso {
            t = t.next_down();
        }
        Threshold::Greater(t)
    }
    fn rule_below(iso: f64) -> Threshold<f32> {
        let mut t = iso as f32;
        if (t as f64) < iso {
            t = t.next_up();
        }
        Threshold::Less(t)
    }
}

impl ThresholdRule for f64 {
    fn rule_above(iso: f64) -> Threshold<f64> {
        Threshold::Greater(iso)
    }
    fn rule_below(iso: f64) -> Threshold<f64> {
        Threshold::Less(iso)
    }
}

fn threshold_above<T: ThresholdRule>(iso: f64) -> Threshold<T> {
    T::rule_above(iso)
}

fn threshold_below<T: ThresholdRule>(iso: f64) -> Threshold<T> {
    T::rule_below(iso)
}

impl_sample!(u8, DType::U8, U8, int);
impl_sample!(i8, DType::I8, I8, int);
impl_sample!(u16, DType::U16, U16, int);
impl_sample!(i16, DType::I16, I16, int);
impl_sample!(u32, DType::U32, U32, int);
impl_sample!(i32, DType::I32, I32, int);
impl_sample!(f32, DType::F32, F32, float);
impl_sample!(f64, DType::F64, F64, float);

fn decode_into<T: Sample>(bytes: &[u8], endian: Endian, out: &mut Vec<T>) {
    out.clear();
    let n = std::mem::size_of::<T>();
    out.reserve(bytes.len() / n);
    match endian {
        Endian::Little => out.extend(bytes.chunks_exact(n).map(T::from_le)),
        Endian::Big => out.extend(bytes.chunks_exact(n).map(T::from_be)),
    }
}

fn read_into<T: Sample>(
    n: usize,
    endian: Endian,
    input: &mut dyn std::io::Read,
    out: &mut Vec<T>,
) -> std::io::Result<()> {
    // Buffers are reused slice after slice: resizing to the same length writes nothing.
    out.truncate(n);
    out.resize(n, T::zeroed());
    input.read_exact(bytemuck::cast_slice_mut(out))?;
    if endian != Endian::NATIVE {
        out.iter_mut().for_each(|x| *x = x.swap_bytes());
    }
    Ok(())
}

fn encode_into<T: Sample>(v: &[T], endian: Endian, out: &mut Vec<u8>) {
    out.reserve(std::mem::size_of_val(v));
    match endian {
        Endian::Little => v.iter().for_each(|x| x.write_le(out)),
        Endian::Big => v.iter().for_each(|x| x.write_be(out)),
    }
}

impl Samples {
    /// An empty buffer of the given type.
    pub fn new(dtype: DType) -> Samples {
        Samples::zeros(dtype, 0)
    }

    /// `n` zero samples.
    pub fn zeros(dtype: DType, n: usize) -> Samples {
        match dtype {
            DType::U8 => Samples::U8(vec![0; n]),
            DType::I8 => Samples::I8(vec![0; n]),
            DType::U16 => Samples::U16(vec![0; n]),
            DType::I16 => Samples::I16(vec![0; n]),
            DType::U32 => Samples::U32(vec![0; n]),
            DType::I32 => Samples::I32(vec![0; n]),
            DType::F32 => Samples::F32(vec![0.0; n]),
            DType::F64 => Samples::F64(vec![0.0; n]),
        }
    }

    /// The type of the samples held.
    pub fn dtype(&self) -> DType {
        match self {
            Samples::U8(_) => DType::U8,
            Samples::I8(_) => DType::I8,
            Samples::U16(_) => DType::U16,
            Samples::I16(_) => DType::I16,
            Samples::U32(_) => DType::U32,
            Samples::I32(_) => DType::I32,
            Samples::F32(_) => DType::F32,
            Samples::F64(_) => DType::F64,
        }
    }

    /// Number of samples held.
    pub fn len(&self) -> usize {
        with_samples!(self, v => v.len())
    }

    /// True when no sample is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sample `i` as `f64` (raw stored value, before any scaling).
    #[inline]
    pub fn get_f64(&self, i: usize) -> f64 {
        with_samples!(self, v => v[i].to_f64())
    }

    /// Sets sample `i` from an `f64` that is representable in the buffer's type.
    pub fn set_f64(&mut self, i: usize, value: f64) {
        match self {
            Samples::U8(v) => v[i] = value as u8,
            Samples::I8(v) => v[i] = value as i8,
            Samples::U16(v) => v[i] = value as u16,
            Samples::I16(v) => v[i] = value as i16,
            Samples::U32(v) => v[i] = value as u32,
            Samples::I32(v) => v[i] = value as i32,
            Samples::F32(v) => v[i] = value as f32,
            Samples::F64(v) => v[i] = value,
        }
    }

    /// Replaces the content with samples decoded from `bytes` (length a multiple of the type size).
    pub fn decode(&mut self, bytes: &[u8], endian: Endian) {
        match self {
            Samples::U8(v) => {
                v.clear();
                v.extend_from_slice(bytes)
            }
            Samples::I8(v) => decode_into(bytes, endian, v),
            Samples::U16(v) => decode_into(bytes, endian, v),
            Samples::I16(v) => decode_into(bytes, endian, v),
            Samples::U32(v) => decode_into(bytes, endian, v),
            Samples::I32(v) => decode_into(bytes, endian, v),
            Samples::F32(v) => decode_into(bytes, endian, v),
            Samples::F64(v) => decode_into(bytes, endian, v),
        }
    }

    /// Replaces the content with `n` samples read from `input` in the given byte order, straight
    /// into the samples' memory (decoding them from a buffer of bytes was a copy more: 5% of the
    /// genus pass on an uncompressed scan).
    pub fn read_from(
        &mut self,
        n: usize,
        endian: Endian,
        input: &mut dyn std::io::Read,
    ) -> std::io::Result<()> {
        match self {
            Samples::U8(v) => read_into(n, endian, input, v),
            Samples::I8(v) => read_into(n, endian, input, v),
            Samples::U16(v) => read_into(n, endian, input, v),
            Samples::I16(v) => read_into(n, endian, input, v),
            Samples::U32(v) => read_into(n, endian, input, v),
            Samples::I32(v) => read_into(n, endian, input, v),
            Samples::F32(v) => read_into(n, endian, input, v),
            Samples::F64(v) => read_into(n, endian, input, v),
        }
    }

    /// Appends the samples' bytes in the given byte order to `out`.
    pub fn encode(&self, endian: Endian, out: &mut Vec<u8>) {
        match self {
            Samples::U8(v) => out.extend_from_slice(v),
            Samples::I8(v) => encode_into(v, endian, out),
            Samples::U16(v) => encode_into(v, endian, out),
            Samples::I16(v) => encode_into(v, endian, out),
            Samples::U32(v) => encode_into(v, endian, out),
            Samples::I32(v) => encode_into(v, endian, out),
            Samples::F32(v) => encode_into(v, endian, out),
            Samples::F64(v) => encode_into(v, endian, out),
        }
    }

    /// Converts to another type, rounding and saturating integers; `None` if a value would be lost
    /// (out of range or non-integral for an integer target, NaN for an integer target).
    pub fn convert_exact(&self, to: DType) -> Option<Samples> {
        if to == self.dtype() {
            return Some(self.clone());
        }
        let (lo, hi) = to.range();
        let mut out = Samples::zeros(to, self.len());
        for i in 0..self.len() {
            let x = self.get_f64(i);
            if !to.is_float() && (x.is_nan() || x < lo || x > hi || x.fract() != 0.0) {
                return None;
            }
            if to == DType::F32 && x.is_finite() && (x as f32) as f64 != x {
                return None;
            }
            out.set_f64(i, x);
        }
        Some(out)
    }
}
