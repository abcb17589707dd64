//! The sides of paired-organ meshes for the offline commands: a text file of `mesh,side`
//! lines (`kidney_03.obj,left`; the file name with or without its extension), `#` comments
//! and blank lines skipped, an optional `mesh,laterality` header.

use std::collections::BTreeMap;
use std::path::Path;

use crate::mesh::Laterality;

/// Sides by mesh name, as the file gives them.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LateralityFile(BTreeMap<String, Laterality>);

impl LateralityFile {
    /// Reads and checks the file at `path`.
    pub fn read(path: &Path) -> Result<Self, String> {
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        Self::parse(&text).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Parses the text of such a file.
    pub fn parse(text: &str) -> Result<Self, String> {
        let mut sides = BTreeMap::new();
        for (number, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let (name, side) = line
                .split_once(',')
                .map(|(n, s)| (n.trim(), s.trim()))
                .ok_or_else(|| format!("line {}: expected mesh,side", number + 1))?;
            if sides.is_empty() && name == "mesh" && side == "laterality" {
                continue;
            }
            let side: Laterality = side
                .parse()
                .map_err(|e| format!("line {}: {e}", number + 1))?;
            if sides.insert(name.to_owned(), side).is_some() {
                return Err(format!("line {}: {name} is listed twice", number + 1));
            }
        }
        Ok(Self(sides))
    }

    /// Fails when the file names a mesh that is not among the mesh files `names`, so that a
    /// misspelt name is not silently ignored.
    pub fn check_names(&self, names: &[String]) -> Result<(), String> {
        match self
            .0
            .keys()
            .find(|k| !names.iter().any(|n| n == *k || stem(n) == k.as_str()))
        {
            Some(unknown) => Err(format!(
                "the laterality file names {unknown}, which is not a mesh file here"
            )),
            None => Ok(()),
        }
    }

    /// The side of each mesh file in `names` (`None` where the file gives none).
    pub fn sides_of(&self, names: &[String]) -> Vec<Option<Laterality>> {
        names
            .iter()
            .map(|n| self.0.get(n).or_else(|| self.0.get(stem(n))).copied())
            .collect()
    }
}

/// A file name without its extension.
fn stem(name: &str) -> &str {
    name.rsplit_once('.').map_or(name, |(s, _)| s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sides_are_read_by_file_name_or_stem() {
        let file = LateralityFile::parse(
            "mesh,laterality\n# the KiTS19 cases\nk_01.obj, left\n\nk_02,RIGHT\n",
        )
        .unwrap();
        let names = ["k_01.obj", "k_02.obj", "k_03.obj"].map(String::from);
        assert_eq!(
            file.sides_of(&names),
            [Some(Laterality::Left), Some(Laterality::Right), None]
        );
        assert!(file.check_names(&names).is_ok());
        let err = file.check_names(&names[..1]).unwrap_err();
        assert!(err.contains("k_02"), "{err}");
    }

    #[test]
    fn malformed_lines_name_their_number() {
        let err = LateralityFile::parse("a.obj,left\nb.obj\n").unwrap_err();
        assert!(err.starts_with("line 2:"), "{err}");
        let err = LateralityFile::parse("a.obj,up\n").unwrap_err();
        assert!(err.contains("'up' is not a side"), "{err}");
        let err = LateralityFile::parse("a.obj,left\na.obj,right\n").unwrap_err();
        assert!(err.contains("twice"), "{err}");
    }
}
