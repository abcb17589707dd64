//! CSV tables (RFC 4180): a header row, then one row per record; fields with a comma, a
//! quote or a line break are quoted. Numbers keep every digit (shortest round-trip form).

/// One field.
#[derive(Debug, Clone, PartialEq)]
pub enum Cell {
    /// Text.
    Text(String),
    /// A number; non-finite values are written as empty fields.
    Number(f64),
    /// A whole number.
    Integer(i64),
    /// `true` or `false`.
    Flag(bool),
    /// An empty field.
    Empty,
}

impl From<&str> for Cell {
    fn from(s: &str) -> Self {
        Self::Text(s.to_owned())
    }
}

impl From<f64> for Cell {
    fn from(v: f64) -> Self {
        Self::Number(v)
    }
}

impl From<usize> for Cell {
    fn from(v: usize) -> Self {
        Self::Integer(i64::try_from(v).unwrap_or(i64::MAX))
    }
}

impl From<bool> for Cell {
    fn from(v: bool) -> Self {
        Self::Flag(v)
    }
}

impl<T: Into<Cell>> From<Option<T>> for Cell {
    fn from(v: Option<T>) -> Self {
        v.map_or(Self::Empty, Into::into)
    }
}

fn quoted(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_owned()
    }
}

impl Cell {
    fn render(&self) -> String {
        match self {
            Self::Text(s) => quoted(s),
            Self::Number(v) if v.is_finite() => format!("{v}"),
            Self::Number(_) | Self::Empty => String::new(),
            Self::Integer(v) => v.to_string(),
            Self::Flag(v) => v.to_string(),
        }
    }
}

/// A table being written.
#[derive(Debug, Clone)]
pub struct Csv {
    out: String,
    columns: usize,
}

impl Csv {
    /// A table with these column names.
    pub fn new<S: AsRef<str>>(header: &[S]) -> Self {
        let mut out = header
            .iter()
            .map(|h| quoted(h.as_ref()))
            .collect::<Vec<_>>()
            .join(",");
        out.push_str("\r\n");
        Self {
            out,
            columns: header.len(),
        }
    }

    /// Appends a row; missing trailing fields are empty, extra ones are dropped.
    pub fn row(&mut self, cells: Vec<Cell>) {
        let mut fields: Vec<String> = cells.iter().take(self.columns).map(Cell::render).collect();
        fields.resize(self.columns, String::new());
        self.out.push_str(&fields.join(","));
        self.out.push_str("\r\n");
    }

    /// The table's text.
    pub fn finish(self) -> String {
        self.out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_are_quoted_only_when_needed_and_numbers_round_trip() {
        let mut csv = Csv::new(&["name", "value", "ok", "n"]);
        csv.row(vec![
            "a, \"b\"".into(),
            0.1.into(),
            true.into(),
            3usize.into(),
        ]);
        csv.row(vec!["plain".into(), f64::NAN.into(), Cell::Empty]);
        assert_eq!(
            csv.finish(),
            "name,value,ok,n\r\n\"a, \"\"b\"\"\",0.1,true,3\r\nplain,,,\r\n"
        );
        let v = 103.123_456_789_012_34_f64;
        assert_eq!(Cell::from(v).render().parse::<f64>().unwrap(), v);
    }
}
