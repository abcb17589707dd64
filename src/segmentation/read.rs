//! Reading NIfTI-1 label volumes (`.nii`, or gzip `.nii.gz` told by its magic bytes).
//!
//! The header is parsed by the `nifti` crate; everything it announces (dimensions, datatype,
//! data offset, voxel count against the limit) is checked here before anything large is
//! allocated, and the voxel data is read here, so a malformed file gives a [`NiftiError`]
//! rather than a panic or a huge allocation.

use std::io::Read;

use flate2::read::MultiGzDecoder;

use super::affine::{Affine, SpatialHeader};
use super::datatype::Datatype;
use super::error::NiftiError;

/// Default largest number of voxels in an uploaded volume (2²⁸, about 268 million).
pub const DEFAULT_MAX_VOXELS: u64 = 1 << 28;
/// Bytes of a NIfTI-1 header.
const HEADER_BYTES: usize = 348;
/// First data byte of a single-file NIfTI-1 (`n+1`) when there are no extensions.
const MIN_VOX_OFFSET: u64 = 352;
/// Largest gap between header and data (extensions) accepted, bytes.
const MAX_EXTENSION_BYTES: u64 = 64 << 20;
/// The gzip magic bytes.
const GZIP_MAGIC: [u8; 2] = [0x1f, 0x8b];

/// Default largest number of samples of the resampled grid (2²⁵, about 33 million).
pub const DEFAULT_MAX_SAMPLES: u64 = 1 << 25;

/// Size limits checked before anything large is allocated.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest number of voxels of the uploaded volume.
    pub max_voxels: u64,
    /// Largest number of samples of the isotropic grid the surface is extracted from.
    pub max_samples: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            max_voxels: DEFAULT_MAX_VOXELS,
            max_samples: DEFAULT_MAX_SAMPLES,
        }
    }
}

/// A 3-D label volume as stored in the file, with its voxel-to-world map.
#[derive(Debug, Clone)]
pub struct LabelVolume {
    /// Voxels along `[i, j, k]`.
    pub dims: [usize; 3],
    /// Voxel index to world millimetres.
    pub affine: Affine,
    /// Voxel type.
    pub datatype: Datatype,
    /// Whether the file is big-endian.
    pub(super) big_endian: bool,
    /// `(scl_slope, scl_inter)` when the file asks for scaling.
    pub(super) scaling: Option<(f64, f64)>,
    /// The raw voxel bytes, `[nk][nj][ni]` with i fastest.
    pub(super) data: Vec<u8>,
}

impl LabelVolume {
    /// Number of voxels.
    pub fn voxel_count(&self) -> usize {
        self.dims.iter().product()
    }
}

/// Reads a NIfTI-1 volume, gzip-compressed or not.
pub fn read(bytes: &[u8], limits: &Limits) -> Result<LabelVolume, NiftiError> {
    if bytes.is_empty() {
        return Err(NiftiError::parse("the file is empty (0 bytes)"));
    }
    if bytes.starts_with(&GZIP_MAGIC) {
        read_stream(MultiGzDecoder::new(bytes), limits, true)
    } else {
        read_stream(bytes, limits, false)
    }
}

fn read_stream(mut input: impl Read, limits: &Limits, gz: bool) -> Result<LabelVolume, NiftiError> {
    let mut raw = Vec::with_capacity(HEADER_BYTES);
    (&mut input)
        .take(HEADER_BYTES as u64)
        .read_to_end(&mut raw)
        .map_err(|e| stream_error(e, gz))?;
    check_size_field(&raw)?;
    let header = nifti::NiftiHeader::from_reader(raw.as_slice())
        .map_err(|e| NiftiError::parse(format!("the header is not valid NIfTI-1 ({e})")))?;
    let layout = Layout::of(&header, limits)?;
    let affine = Affine::from_header(&spatial(&header))?;
    let skip = layout.vox_offset - HEADER_BYTES as u64;
    let skipped = std::io::copy(&mut (&mut input).take(skip), &mut std::io::sink())
        .map_err(|e| stream_error(e, gz))?;
    let mut data = Vec::new();
    if skipped == skip {
        data.try_reserve_exact(layout.data_bytes as usize)
            .map_err(|_| NiftiError::parse("the volume does not fit in memory"))?;
        input
            .take(layout.data_bytes)
            .read_to_end(&mut data)
            .map_err(|e| stream_error(e, gz))?;
    }
    if data.len() as u64 != layout.data_bytes {
        return Err(NiftiError::parse(format!(
            "the file is truncated: the header announces {} voxels of {} ({} bytes from byte {}), \
             but only {} bytes of voxel data follow",
            layout.dims.iter().product::<usize>(),
            layout.datatype.name(),
            layout.data_bytes,
            layout.vox_offset,
            data.len()
        )));
    }
    Ok(LabelVolume {
        dims: layout.dims,
        affine,
        datatype: layout.datatype,
        big_endian: header.endianness == nifti::Endianness::Big,
        scaling: scaling(header.scl_slope, header.scl_inter),
        data,
    })
}

fn stream_error(e: std::io::Error, gz: bool) -> NiftiError {
    if gz {
        NiftiError::parse(format!(
            "the gzip stream is damaged ({e}); compress the file again"
        ))
    } else {
        NiftiError::parse(format!("the file could not be read ({e})"))
    }
}

/// `sizeof_hdr` tells NIfTI-1 (348) from NIfTI-2 (540) and from anything else.
fn check_size_field(raw: &[u8]) -> Result<(), NiftiError> {
    if raw.len() < HEADER_BYTES {
        return Err(NiftiError::parse(format!(
            "the file has {} bytes, fewer than the {HEADER_BYTES} of a NIfTI-1 header",
            raw.len()
        )));
    }
    let first = [raw[0], raw[1], raw[2], raw[3]];
    let size = [i32::from_le_bytes(first), i32::from_be_bytes(first)];
    if size.contains(&540) {
        return Err(NiftiError::UnsupportedFormat {
            what: "NIfTI-2".into(),
            fix: "save the segmentation as NIfTI-1 (.nii or .nii.gz)".into(),
        });
    }
    if !size.contains(&(HEADER_BYTES as i32)) {
        return Err(NiftiError::parse(
            "bad magic: the file does not start with a NIfTI-1 header (sizeof_hdr is not 348); \
             upload a .nii or .nii.gz label volume",
        ));
    }
    Ok(())
}

/// What the header says about the data block, checked.
struct Layout {
    dims: [usize; 3],
    datatype: Datatype,
    vox_offset: u64,
    data_bytes: u64,
}

impl Layout {
    fn of(h: &nifti::NiftiHeader, limits: &Limits) -> Result<Self, NiftiError> {
        match &h.magic {
            b"n+1\0" => {}
            b"ni1\0" => {
                return Err(NiftiError::UnsupportedFormat {
                    what: "a NIfTI-1 header/image pair (.hdr + .img)".into(),
                    fix: "convert it to a single .nii or .nii.gz file".into(),
                });
            }
            _ => return Err(NiftiError::parse("bad magic: expected 'n+1' at byte 344")),
        }
        let dims = dimensions(&h.dim)?;
        let datatype = Datatype::from_code(h.datatype)?;
        let voxels = dims.iter().map(|&d| d as u64).product::<u64>();
        if voxels > limits.max_voxels {
            return Err(NiftiError::TooLarge {
                what: "the volume",
                count: voxels,
                limit: limits.max_voxels,
                fix: "crop the volume around the structure before uploading",
            });
        }
        let offset = f64::from(h.vox_offset);
        if !offset.is_finite()
            || offset < 0.0
            || offset > (MIN_VOX_OFFSET + MAX_EXTENSION_BYTES) as f64
        {
            return Err(NiftiError::parse(format!(
                "vox_offset {} is not a usable data position",
                h.vox_offset
            )));
        }
        Ok(Self {
            dims,
            datatype,
            vox_offset: (offset as u64).max(MIN_VOX_OFFSET),
            data_bytes: voxels * datatype.bytes() as u64,
        })
    }
}

/// The three spatial sizes; further dimensions must be 1.
fn dimensions(dim: &[u16; 8]) -> Result<[usize; 3], NiftiError> {
    let rank = dim[0] as usize;
    if !(1..=7).contains(&rank) {
        return Err(NiftiError::parse(format!(
            "dim[0] is {}, but it must give the number of dimensions (1 to 7)",
            dim[0]
        )));
    }
    let mut dims = [1usize; 3];
    for a in 1..=rank {
        let n = dim[a];
        if n == 0 || n > i16::MAX as u16 {
            return Err(NiftiError::parse(format!(
                "dim[{a}] is {}, but every size must be between 1 and 32767",
                n as i16
            )));
        }
        if a <= 3 {
            dims[a - 1] = n as usize;
        } else if n > 1 {
            return Err(NiftiError::UnsupportedFormat {
                what: format!("a {rank}-D volume with {n} entries along dimension {a}"),
                fix: "upload a single 3-D label volume".into(),
            });
        }
    }
    Ok(dims)
}

fn scaling(slope: f32, inter: f32) -> Option<(f64, f64)> {
    let (slope, inter) = (f64::from(slope), f64::from(inter));
    let scaled = slope.is_finite() && slope != 0.0 && inter.is_finite();
    (scaled && (slope != 1.0 || inter != 0.0)).then_some((slope, inter))
}

fn spatial(h: &nifti::NiftiHeader) -> SpatialHeader {
    let mm_per_unit = match h.xyzt_units & 0x07 {
        1 => 1000.0,
        3 => 0.001,
        _ => 1.0,
    };
    SpatialHeader {
        sform_code: h.sform_code,
        qform_code: h.qform_code,
        srow: [h.srow_x, h.srow_y, h.srow_z],
        quatern: [h.quatern_b, h.quatern_c, h.quatern_d],
        qoffset: [h.quatern_x, h.quatern_y, h.quatern_z],
        pixdim: [h.pixdim[0], h.pixdim[1], h.pixdim[2], h.pixdim[3]],
        mm_per_unit,
    }
}
