//! Writing small NIfTI-1 label volumes (uint8, sform), for tests, examples and exports.

use std::io::Write;

use flate2::Compression;
use flate2::write::GzEncoder;

use super::affine::Affine;

/// Bytes before the voxel data: the 348-byte header and the 4-byte extension flag.
const DATA_OFFSET: usize = 352;

/// Encodes a uint8 label volume of `dims` (`labels` i fastest, `[ni * nj * nk]`) with
/// `affine` as its sform (code 2, aligned), in mm; gzip-compressed when `gzip`.
///
/// `labels` shorter than the volume is padded with background, longer is cut.
pub fn encode_labels(dims: [usize; 3], labels: &[u8], affine: &Affine, gzip: bool) -> Vec<u8> {
    let mut out = vec![0u8; DATA_OFFSET];
    let put_i16 =
        |out: &mut Vec<u8>, at: usize, v: i16| out[at..at + 2].copy_from_slice(&v.to_le_bytes());
    let put_f32 = |out: &mut Vec<u8>, at: usize, v: f64| {
        out[at..at + 4].copy_from_slice(&(v as f32).to_le_bytes())
    };
    out[0..4].copy_from_slice(&348i32.to_le_bytes());
    put_i16(&mut out, 40, 3);
    for (a, &n) in dims.iter().enumerate() {
        put_i16(&mut out, 42 + 2 * a, n.min(i16::MAX as usize) as i16);
    }
    for a in 3..7 {
        put_i16(&mut out, 42 + 2 * a, 1);
    }
    put_i16(&mut out, 70, 2); // datatype uint8
    put_i16(&mut out, 72, 8); // bitpix
    put_f32(&mut out, 76, 1.0); // qfac
    for (a, s) in affine.spacing_mm().iter().enumerate() {
        put_f32(&mut out, 80 + 4 * a, *s);
    }
    put_f32(&mut out, 108, DATA_OFFSET as f64);
    put_f32(&mut out, 112, 1.0); // scl_slope
    out[123] = 2; // spatial unit: mm
    put_i16(&mut out, 254, 2); // sform_code: aligned
    for r in 0..3 {
        for c in 0..3 {
            put_f32(&mut out, 280 + 16 * r + 4 * c, affine.linear[r][c]);
        }
        put_f32(&mut out, 280 + 16 * r + 12, affine.offset[r]);
    }
    out[344..348].copy_from_slice(b"n+1\0");
    let n: usize = dims.iter().product();
    out.extend(labels.iter().take(n));
    out.resize(DATA_OFFSET + n, 0);
    if !gzip {
        return out;
    }
    let mut encoder = GzEncoder::new(Vec::new(), Compression::fast());
    // Writing to a Vec cannot fail.
    let _ = encoder.write_all(&out);
    encoder.finish().unwrap_or_default()
}
