//! Agreement between two partitions of the same items: the adjusted Rand index (Hubert and
//! Arabie, 1985), used to score recovered clusters against known sub-population labels.

use std::collections::BTreeMap;

use super::EvalError;

/// `n choose 2` as a float.
fn pairs(n: usize) -> f64 {
    let n = n as f64;
    n * (n - 1.0) / 2.0
}

/// The adjusted Rand index of two labellings of the same items: 1 for identical partitions
/// (whatever the label names), about 0 for independent ones, negative below chance. Two
/// partitions that both put every item in one cluster score 1.
pub fn adjusted_rand_index(a: &[usize], b: &[usize]) -> Result<f64, EvalError> {
    if a.len() != b.len() {
        return Err(EvalError::DimensionMismatch {
            what: "labels of the two partitions",
            expected: a.len(),
            found: b.len(),
        });
    }
    if a.len() < 2 {
        return Err(EvalError::TooFewValues {
            what: "labelled items",
            required: 2,
            found: a.len(),
        });
    }
    let mut table: BTreeMap<(usize, usize), usize> = BTreeMap::new();
    let mut rows: BTreeMap<usize, usize> = BTreeMap::new();
    let mut columns: BTreeMap<usize, usize> = BTreeMap::new();
    for (&x, &y) in a.iter().zip(b) {
        *table.entry((x, y)).or_default() += 1;
        *rows.entry(x).or_default() += 1;
        *columns.entry(y).or_default() += 1;
    }
    let index: f64 = table.values().map(|&n| pairs(n)).sum();
    let row_pairs: f64 = rows.values().map(|&n| pairs(n)).sum();
    let column_pairs: f64 = columns.values().map(|&n| pairs(n)).sum();
    let expected = row_pairs * column_pairs / pairs(a.len());
    let max = (row_pairs + column_pairs) / 2.0;
    if (max - expected).abs() < f64::EPSILON {
        return Ok(1.0);
    }
    Ok((index - expected) / (max - expected))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_partitions_score_one_whatever_the_labels() {
        let a = [0, 0, 1, 1, 2, 2];
        let renamed = [5, 5, 3, 3, 9, 9];
        assert!((adjusted_rand_index(&a, &renamed).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(adjusted_rand_index(&[0, 0, 0], &[1, 1, 1]).unwrap(), 1.0);
    }

    #[test]
    fn a_hand_computed_example() {
        // a = {0,1,2 | 3,4,5}, b = {0,1 | 2,3 | 4,5}. Contingency [[2,1,0],[0,1,2]]: index
        // = 1 + 1 = 2; rows C(3,2)·2 = 6; columns C(2,2)·3 = 3; expected 6·3/15 = 1.2;
        // max 4.5; ARI = (2 − 1.2)/(4.5 − 1.2) = 0.8/3.3.
        let a = [0, 0, 0, 1, 1, 1];
        let b = [0, 0, 1, 1, 2, 2];
        let ari = adjusted_rand_index(&a, &b).unwrap();
        assert!((ari - 0.8 / 3.3).abs() < 1e-12, "{ari}");
        // Splitting every pair across clusters is worse than chance.
        let crossed = adjusted_rand_index(&[0, 0, 1, 1], &[0, 1, 0, 1]).unwrap();
        assert!(crossed < 0.0, "{crossed}");
    }

    #[test]
    fn mismatched_or_tiny_inputs_are_errors() {
        assert_eq!(
            adjusted_rand_index(&[0, 1], &[0]).unwrap_err().code(),
            "eval.dimension_mismatch"
        );
        assert_eq!(
            adjusted_rand_index(&[0], &[0]).unwrap_err().code(),
            "eval.too_few_values"
        );
    }
}
