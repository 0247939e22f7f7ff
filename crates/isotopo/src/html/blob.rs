//! The report's binary payload: little-endian arrays one after another, each starting at a
//! multiple of 4 bytes (so the page can view them as typed arrays in place), embedded in the
//! HTML gzip-compressed and base64-encoded (the browser inflates it with `DecompressionStream`).
//!
//! A mesh's arrays are delta-coded: each value minus the one `stride` before it, wrapping
//! (vertex codes per axis, triangle indices one after another). Marching cubes makes vertices
//! and triangles in sweep order, so the deltas are small and gzip packs them about three times
//! tighter than the values.

use base64::Engine;
use std::io::Write;

#[derive(Default)]
pub(crate) struct Blob {
    bytes: Vec<u8>,
}

impl Blob {
    /// Appends a mesh: `codes` (three u16 a vertex) and `triangles` (three indices each, as u16
    /// when there are at most 65,536 vertices), delta-coded. Returns the byte offsets of both,
    /// and the indices' width in bytes.
    pub fn push_mesh(&mut self, codes: &[u16], triangles: &[u32]) -> (usize, usize, usize) {
        let deltas: Vec<u16> = (0..codes.len())
            .map(|k| codes[k].wrapping_sub(if k >= 3 { codes[k - 3] } else { 0 }))
            .collect();
        let v = self.push_u16(&deltas);
        let index_deltas: Vec<u32> = (0..triangles.len())
            .map(|k| triangles[k].wrapping_sub(if k >= 1 { triangles[k - 1] } else { 0 }))
            .collect();
        if codes.len() / 3 <= 1 << 16 {
            let narrow: Vec<u16> = index_deltas.iter().map(|&d| d as u16).collect();
            (v, self.push_u16(&narrow), 2)
        } else {
            (v, self.push_u32(&index_deltas), 4)
        }
    }

    /// Appends `values`; returns their byte offset.
    pub fn push_u16(&mut self, values: &[u16]) -> usize {
        let at = self.bytes.len();
        self.bytes
            .extend(values.iter().flat_map(|v| v.to_le_bytes()));
        self.pad();
        at
    }

    /// Appends `values`; returns their byte offset.
    pub fn push_u32(&mut self, values: &[u32]) -> usize {
        let at = self.bytes.len();
        self.bytes
            .extend(values.iter().flat_map(|v| v.to_le_bytes()));
        at
    }

    fn pad(&mut self) {
        while !self.bytes.len().is_multiple_of(4) {
            self.bytes.push(0);
        }
    }

    /// Bytes so far.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// The bytes, gzip-compressed, in base64.
    pub fn to_base64_gzip(&self) -> String {
        gzip_base64(&self.bytes)
    }

    /// A mesh's arrays back from [`Blob::push_mesh`]'s offsets: codes and indices.
    #[cfg(test)]
    pub fn mesh(
        &self,
        v: usize,
        vertices: usize,
        t: usize,
        triangles: usize,
    ) -> (Vec<u16>, Vec<u32>) {
        let mut codes = self.u16s(v, 3 * vertices);
        for k in 3..codes.len() {
            codes[k] = codes[k].wrapping_add(codes[k - 3]);
        }
        let mut idx: Vec<u32> = if vertices <= 1 << 16 {
            self.u16s(t, 3 * triangles)
                .into_iter()
                .map(u32::from)
                .collect()
        } else {
            self.u32s(t, 3 * triangles)
        };
        for k in 1..idx.len() {
            let width = if vertices <= 1 << 16 {
                1u64 << 16
            } else {
                1u64 << 32
            };
            idx[k] = ((idx[k] as u64 + idx[k - 1] as u64) % width) as u32;
        }
        (codes, idx)
    }

    #[cfg(test)]
    pub fn u16s(&self, at: usize, n: usize) -> Vec<u16> {
        self.bytes[at..at + 2 * n]
            .chunks(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect()
    }

    #[cfg(test)]
    pub fn u32s(&self, at: usize, n: usize) -> Vec<u32> {
        self.bytes[at..at + 4 * n]
            .chunks(4)
            .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    }
}

/// `bytes` gzip-compressed, in base64 (the report's encoding of everything large).
pub(crate) fn gzip_base64(bytes: &[u8]) -> String {
    // Writing to a Vec cannot fail.
    gzip_base64_with(|w| w.write_all(bytes)).unwrap_or_default()
}

/// What `write` writes, gzip-compressed as it goes (only the compressed bytes are held), in
/// base64.
pub(crate) fn gzip_base64_with(
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> std::io::Result<String> {
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    write(&mut gz)?;
    let packed = gz.finish()?;
    Ok(base64::engine::general_purpose::STANDARD.encode(packed))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrays_start_on_four_bytes_and_round_trip() {
        let mut b = Blob::default();
        let a = b.push_u16(&[1, 2, 3]);
        let t = b.push_u32(&[70000, 5]);
        assert_eq!((a, t), (0, 8));
        assert_eq!(b.u16s(a, 3), vec![1, 2, 3]);
        assert_eq!(b.u32s(t, 2), vec![70000, 5]);
        let text = b.to_base64_gzip();
        let packed = base64::engine::general_purpose::STANDARD
            .decode(text)
            .unwrap();
        let mut out = Vec::new();
        use std::io::Read;
        flate2::read::GzDecoder::new(&packed[..])
            .read_to_end(&mut out)
            .unwrap();
        assert_eq!(out, b.bytes);
    }

    #[test]
    fn meshes_round_trip_through_their_deltas() {
        let mut b = Blob::default();
        b.push_u16(&[9]);
        let codes = [5u16, 65535, 0, 7, 1, 65000, 6, 2, 3];
        let tris = [0u32, 1, 2, 2, 1, 0];
        let (v, t, wide) = b.push_mesh(&codes, &tris);
        assert_eq!(wide, 2);
        assert_eq!(b.mesh(v, 3, t, 2), (codes.to_vec(), tris.to_vec()));
        let many: Vec<u16> = (0..3 * 70_000).map(|k| (k * 7919 % 65536) as u16).collect();
        let tris = [69_999u32, 3, 65_537, 0, 1, 2];
        let (v, t, wide) = b.push_mesh(&many, &tris);
        assert_eq!(wide, 4);
        assert_eq!(b.mesh(v, 70_000, t, 2), (many, tris.to_vec()));
    }
}
