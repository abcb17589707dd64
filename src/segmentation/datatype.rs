//! NIfTI voxel types that can hold labels, and decoding voxels into integer labels.

use super::error::NiftiError;
use super::read::LabelVolume;

/// A voxel type that can hold labels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Datatype {
    /// `uint8` (code 2).
    U8,
    /// `int16` (code 4).
    I16,
    /// `int32` (code 8).
    I32,
    /// `float32` (code 16).
    F32,
    /// `float64` (code 64).
    F64,
    /// `int8` (code 256).
    I8,
    /// `uint16` (code 512).
    U16,
    /// `uint32` (code 768).
    U32,
    /// `int64` (code 1024).
    I64,
    /// `uint64` (code 1280).
    U64,
}

/// Largest distance of a float label from a whole number.
pub const LABEL_TOLERANCE: f64 = 1e-4;

impl Datatype {
    /// The type of a NIfTI datatype code.
    pub fn from_code(code: i16) -> Result<Self, NiftiError> {
        Ok(match code {
            2 => Datatype::U8,
            4 => Datatype::I16,
            8 => Datatype::I32,
            16 => Datatype::F32,
            64 => Datatype::F64,
            256 => Datatype::I8,
            512 => Datatype::U16,
            768 => Datatype::U32,
            1024 => Datatype::I64,
            1280 => Datatype::U64,
            _ => {
                let name = match code {
                    1 => "binary",
                    32 => "complex64",
                    128 => "rgb24",
                    1536 => "float128",
                    1792 => "complex128",
                    2048 => "complex256",
                    2304 => "rgba32",
                    _ => "unknown",
                };
                return Err(NiftiError::UnsupportedDatatype { code, name });
            }
        })
    }

    /// The NIfTI datatype code.
    pub fn code(self) -> i16 {
        match self {
            Datatype::U8 => 2,
            Datatype::I16 => 4,
            Datatype::I32 => 8,
            Datatype::F32 => 16,
            Datatype::F64 => 64,
            Datatype::I8 => 256,
            Datatype::U16 => 512,
            Datatype::U32 => 768,
            Datatype::I64 => 1024,
            Datatype::U64 => 1280,
        }
    }

    /// Bytes per voxel.
    pub fn bytes(self) -> usize {
        match self {
            Datatype::U8 | Datatype::I8 => 1,
            Datatype::I16 | Datatype::U16 => 2,
            Datatype::I32 | Datatype::U32 | Datatype::F32 => 4,
            Datatype::I64 | Datatype::U64 | Datatype::F64 => 8,
        }
    }

    /// The NIfTI name, e.g. `uint8`.
    pub fn name(self) -> &'static str {
        match self {
            Datatype::U8 => "uint8",
            Datatype::I16 => "int16",
            Datatype::I32 => "int32",
            Datatype::F32 => "float32",
            Datatype::F64 => "float64",
            Datatype::I8 => "int8",
            Datatype::U16 => "uint16",
            Datatype::U32 => "uint32",
            Datatype::I64 => "int64",
            Datatype::U64 => "uint64",
        }
    }
}

/// Decodes `N`-byte voxels with `decode` and calls `visit(voxel, value)` for each.
fn each<const N: usize>(
    data: &[u8],
    decode: impl Fn([u8; N]) -> f64,
    mut visit: impl FnMut(usize, f64),
) {
    let mut word = [0u8; N];
    for (i, chunk) in data.chunks_exact(N).enumerate() {
        word.copy_from_slice(chunk);
        visit(i, decode(word));
    }
}

macro_rules! decode_as {
    ($t:ty, $big:expr) => {
        move |w| {
            if $big {
                <$t>::from_be_bytes(w) as f64
            } else {
                <$t>::from_le_bytes(w) as f64
            }
        }
    };
}

impl LabelVolume {
    /// Calls `visit(voxel, label)` for every voxel in file order (i fastest), after
    /// scaling; fails on the first value that is not a whole number.
    pub fn for_each_label(&self, mut visit: impl FnMut(usize, i64)) -> Result<(), NiftiError> {
        let (slope, inter) = self.scaling.unwrap_or((1.0, 0.0));
        let mut bad: Option<(usize, f64)> = None;
        let mut on_value = |i: usize, raw: f64| {
            let v = raw * slope + inter;
            let label = v.round();
            if (v - label).abs() <= LABEL_TOLERANCE && label.abs() < 9.0e15 {
                visit(i, label as i64);
            } else if bad.is_none() {
                bad = Some((i, v));
            }
        };
        let big = self.big_endian;
        let d = &self.data;
        match self.datatype {
            Datatype::U8 => each(d, |w: [u8; 1]| f64::from(w[0]), &mut on_value),
            Datatype::I8 => each(d, |w: [u8; 1]| f64::from(w[0] as i8), &mut on_value),
            Datatype::I16 => each(d, decode_as!(i16, big), &mut on_value),
            Datatype::U16 => each(d, decode_as!(u16, big), &mut on_value),
            Datatype::I32 => each(d, decode_as!(i32, big), &mut on_value),
            Datatype::U32 => each(d, decode_as!(u32, big), &mut on_value),
            Datatype::I64 => each(d, decode_as!(i64, big), &mut on_value),
            Datatype::U64 => each(d, decode_as!(u64, big), &mut on_value),
            Datatype::F32 => each(d, decode_as!(f32, big), &mut on_value),
            Datatype::F64 => each(d, decode_as!(f64, big), &mut on_value),
        }
        match bad {
            Some((i, value)) => {
                let [ni, nj, _] = self.dims;
                Err(NiftiError::NotLabels {
                    value,
                    voxel: [i % ni, (i / ni) % nj, i / (ni * nj)],
                })
            }
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_round_trip_and_unsupported_types_are_named() {
        for code in [2, 4, 8, 16, 64, 256, 512, 768, 1024, 1280] {
            assert_eq!(Datatype::from_code(code).unwrap().code(), code);
        }
        let e = Datatype::from_code(128).unwrap_err();
        assert_eq!(e.code(), "nifti.unsupported_datatype");
        assert!(e.to_string().contains("128 (rgb24)"), "{e}");
        assert_eq!(Datatype::U16.bytes(), 2);
    }
}
