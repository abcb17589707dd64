//! Label selection, 6-connected components and hole filling on voxel masks.

use std::collections::BTreeMap;

use super::datatype::Datatype;
use super::error::NiftiError;
use super::field::{Mask, linear};
use super::read::LabelVolume;

/// Voxel count of every label value in a volume (background 0 included).
pub type LabelCounts = BTreeMap<i64, u64>;

/// The voxels holding any of `labels`, cropped to their bounding box plus one voxel of
/// background on every side, and the voxel count of every label in the volume.
pub fn select(volume: &LabelVolume, labels: &[i64]) -> Result<(Mask, LabelCounts), NiftiError> {
    let mut chosen = vec![0u64; volume.voxel_count().div_ceil(64)];
    let counts = match scan_small_integers(volume, labels, &mut chosen) {
        Some(counts) => counts,
        None => scan_any(volume, labels, &mut chosen)?,
    };
    let Some((lo, hi)) = bounds_of(&chosen, volume.dims) else {
        return Err(NiftiError::EmptyLabel {
            requested: labels.to_vec(),
            present: counts
                .iter()
                .filter(|(l, _)| **l != 0)
                .map(|(&l, &n)| (l, n))
                .collect(),
        });
    };
    let crop = [0, 1, 2].map(|a| hi[a] - lo[a] + 3);
    let mut mask = Mask::empty(crop, [0, 1, 2].map(|a| lo[a] as i64 - 1));
    for z in lo[2]..=hi[2] {
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                let i = linear(volume.dims, [x, y, z]);
                if chosen[i / 64] >> (i % 64) & 1 == 1 {
                    let local = [x - lo[0] + 1, y - lo[1] + 1, z - lo[2] + 1];
                    mask.inside[linear(crop, local)] = true;
                }
            }
        }
    }
    Ok((mask, counts))
}

/// Any datatype: decode every voxel to a label.
fn scan_any(
    volume: &LabelVolume,
    labels: &[i64],
    chosen: &mut [u64],
) -> Result<LabelCounts, NiftiError> {
    let mut counts = LabelCounts::new();
    let (mut run_label, mut run) = (0i64, 0u64);
    volume.for_each_label(|i, label| {
        if label == run_label {
            run += 1;
        } else {
            if run > 0 {
                *counts.entry(run_label).or_default() += run;
            }
            (run_label, run) = (label, 1);
        }
        if labels.contains(&label) {
            chosen[i / 64] |= 1 << (i % 64);
        }
    })?;
    if run > 0 {
        *counts.entry(run_label).or_default() += run;
    }
    Ok(counts)
}

/// 8- and 16-bit integers without scaling (nearly every label volume): a lookup table per
/// code instead of decoding each voxel. `None` for other volumes.
fn scan_small_integers(
    volume: &LabelVolume,
    labels: &[i64],
    chosen: &mut [u64],
) -> Option<LabelCounts> {
    let (width, signed) = match (volume.datatype, volume.scaling) {
        (Datatype::U8, None) => (1, false),
        (Datatype::I8, None) => (1, true),
        (Datatype::U16, None) => (2, false),
        (Datatype::I16, None) => (2, true),
        _ => return None,
    };
    let label_of = |code: usize| -> i64 {
        match (width, signed) {
            (1, true) => i64::from(code as u8 as i8),
            (2, true) => i64::from(code as u16 as i16),
            _ => code as i64,
        }
    };
    let codes = 1usize << (8 * width);
    let wanted: Vec<bool> = (0..codes).map(|c| labels.contains(&label_of(c))).collect();
    let mut histogram = vec![0u64; codes];
    let mut mark = |i: usize, code: usize| {
        histogram[code] += 1;
        if wanted[code] {
            chosen[i / 64] |= 1 << (i % 64);
        }
    };
    if width == 1 {
        for (i, &b) in volume.data.iter().enumerate() {
            mark(i, b as usize);
        }
    } else {
        for (i, w) in volume.data.chunks_exact(2).enumerate() {
            let code = if volume.big_endian {
                u16::from_be_bytes([w[0], w[1]])
            } else {
                u16::from_le_bytes([w[0], w[1]])
            };
            mark(i, code as usize);
        }
    }
    Some(
        (0..codes)
            .filter(|&c| histogram[c] > 0)
            .map(|c| (label_of(c), histogram[c]))
            .collect(),
    )
}

/// Smallest and largest index per axis of the set bits, `None` when none is set.
fn bounds_of(chosen: &[u64], dims: [usize; 3]) -> Option<([usize; 3], [usize; 3])> {
    let mut lo = [usize::MAX; 3];
    let mut hi = [0usize; 3];
    for (w, &word) in chosen.iter().enumerate().filter(|(_, w)| **w != 0) {
        let mut bits = word;
        while bits != 0 {
            let i = w * 64 + bits.trailing_zeros() as usize;
            bits &= bits - 1;
            let p = [
                i % dims[0],
                (i / dims[0]) % dims[1],
                i / (dims[0] * dims[1]),
            ];
            for a in 0..3 {
                lo[a] = lo[a].min(p[a]);
                hi[a] = hi[a].max(p[a]);
            }
        }
    }
    (lo[0] <= hi[0]).then_some((lo, hi))
}

/// The face neighbours (6-connectivity) of voxel `i` in a grid of `dims`.
fn neighbours(dims: [usize; 3], i: usize) -> impl Iterator<Item = usize> {
    let [nx, ny, nz] = dims;
    let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
    let plane = nx * ny;
    [
        (x > 0).then(|| i - 1),
        (x + 1 < nx).then(|| i + 1),
        (y > 0).then(|| i - nx),
        (y + 1 < ny).then(|| i + nx),
        (z > 0).then(|| i - plane),
        (z + 1 < nz).then(|| i + plane),
    ]
    .into_iter()
    .flatten()
}

/// Marks every voxel reachable from `seeds` through voxels where `passable` is true.
fn flood(
    dims: [usize; 3],
    seeds: Vec<usize>,
    passable: impl Fn(usize) -> bool,
    reached: &mut [bool],
) {
    let mut stack = seeds;
    for &s in &stack {
        reached[s] = true;
    }
    while let Some(i) = stack.pop() {
        for j in neighbours(dims, i) {
            if !reached[j] && passable(j) {
                reached[j] = true;
                stack.push(j);
            }
        }
    }
}

/// 6-connected components of the inside voxels: a component number per voxel (`u32::MAX`
/// outside), numbered in scan order, and the voxel count of each.
pub fn components(mask: &Mask) -> (Vec<u32>, Vec<usize>) {
    let mut label = vec![u32::MAX; mask.inside.len()];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..mask.inside.len() {
        if !mask.inside[start] || label[start] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        let mut size = 0;
        label[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            size += 1;
            for j in neighbours(mask.dims, i) {
                if mask.inside[j] && label[j] == u32::MAX {
                    label[j] = id;
                    stack.push(j);
                }
            }
        }
        sizes.push(size);
    }
    (label, sizes)
}

/// Keeps only the largest 6-connected component (the first in scan order on a tie);
/// returns how many components there were.
pub fn keep_largest_component(mask: &mut Mask) -> usize {
    let (label, sizes) = components(mask);
    let Some(largest) = (0..sizes.len()).max_by_key(|&c| (sizes[c], std::cmp::Reverse(c))) else {
        return 0;
    };
    for (inside, l) in mask.inside.iter_mut().zip(label) {
        *inside = l == largest as u32;
    }
    sizes.len()
}

/// Fills background cavities: outside voxels not 6-connected to the mask's border.
/// Returns the number of voxels filled.
pub fn fill_holes(mask: &mut Mask) -> usize {
    let dims = mask.dims;
    let [nx, ny, nz] = dims;
    let seeds: Vec<usize> = (0..mask.inside.len())
        .filter(|&i| {
            let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
            let border = x == 0 || y == 0 || z == 0 || x + 1 == nx || y + 1 == ny || z + 1 == nz;
            border && !mask.inside[i]
        })
        .collect();
    let mut outside = vec![false; mask.inside.len()];
    let inside = &mask.inside;
    flood(dims, seeds, |j| !inside[j], &mut outside);
    let mut filled = 0;
    for (v, reached) in mask.inside.iter_mut().zip(outside) {
        if !*v && !reached {
            *v = true;
            filled += 1;
        }
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mask_from(dims: [usize; 3], inside: &[[usize; 3]]) -> Mask {
        let mut m = Mask::empty(dims, [0; 3]);
        for &p in inside {
            m.inside[linear(dims, p)] = true;
        }
        m
    }

    #[test]
    fn diagonal_neighbours_are_separate_components() {
        let mut m = mask_from(
            [4, 4, 4],
            &[
                [0, 0, 0],
                [1, 0, 0],
                [2, 1, 0],
                [2, 1, 1],
                [2, 2, 1],
                [3, 3, 3],
            ],
        );
        let (_, sizes) = components(&m);
        assert_eq!(sizes, vec![2, 3, 1]);
        assert_eq!(keep_largest_component(&mut m), 3);
        assert_eq!(m.count(), 3);
        assert!(m.inside[linear([4, 4, 4], [2, 2, 1])]);
    }

    #[test]
    fn a_closed_cavity_is_filled_and_an_open_one_is_not() {
        // A 5×5×5 shell: its 3×3×3 inside is a cavity.
        let dims = [7, 7, 7];
        let mut shell = Vec::new();
        for z in 1..6 {
            for y in 1..6 {
                for x in 1..6 {
                    let on_face = [x, y, z].iter().any(|&c| c == 1 || c == 5);
                    if on_face {
                        shell.push([x, y, z]);
                    }
                }
            }
        }
        let mut closed = mask_from(dims, &shell);
        assert_eq!(fill_holes(&mut closed), 27);
        assert_eq!(closed.count(), 125);
        // A hole in one face opens the cavity to the outside.
        let open: Vec<[usize; 3]> = shell.iter().copied().filter(|&p| p != [3, 3, 1]).collect();
        let mut open = mask_from(dims, &open);
        assert_eq!(fill_holes(&mut open), 0);
    }
}
