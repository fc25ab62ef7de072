//! The one reader of igi's small numeric CSV tables (BRDF samples, direction pairs,
//! lumitexels, Fresnel reflectance, correspondences, sample points).
//!
//! The dialect every table shares: a header row first (its column names matched without regard
//! to case), cells split on `,` and trimmed, blank lines and lines starting with `#` skipped, a
//! UTF-8 byte-order mark (spreadsheet exports) ignored. Quoting is not part of the dialect: no
//! igi table holds a comma inside a cell. Every error names the file and, for a row, its
//! 1-based line number, in the words the readers have always used.

use std::fmt;
use std::path::{Path, PathBuf};

/// What is wrong with a table or one of its rows.
#[derive(Clone, Debug, PartialEq)]
pub enum CsvProblem {
    /// No header row (the file is empty or only comments).
    Empty,
    /// No data row after the header.
    NoRows { what: &'static str },
    /// The header lacks a column the reader needs.
    MissingColumn { name: String, have: String },
    /// A row has another number of cells than the header.
    CellCount { got: usize, want: usize },
    /// A row is too short to hold the named column.
    MissingValue { name: String, cells: usize },
    /// A cell that should hold a number does not.
    NotNumber { name: String, cell: String },
    /// A cell holds an infinite or NaN number.
    NotFinite { name: String, cell: String },
    /// A header-less row of numbers has the wrong count or a non-number.
    NumberRow { want: usize, columns: &'static str },
}

impl fmt::Display for CsvProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CsvProblem::Empty => f.write_str("empty file (no header)"),
            CsvProblem::NoRows { what } => write!(f, "no {what} after the header"),
            CsvProblem::MissingColumn { name, have } => {
                write!(f, "header lacks column `{name}` (have: {have})")
            }
            CsvProblem::CellCount { got, want } => write!(f, "{got} cells, header has {want}"),
            CsvProblem::MissingValue { name, cells } => {
                write!(f, "missing value for `{name}` ({cells} cells)")
            }
            CsvProblem::NotNumber { name, cell } => {
                write!(f, "`{name}` = `{cell}` is not a number")
            }
            CsvProblem::NotFinite { name, cell } => write!(f, "`{name}` = `{cell}` is not finite"),
            CsvProblem::NumberRow { want, columns } => {
                write!(f, "expected {want} finite numbers {columns}")
            }
        }
    }
}

/// A problem in a CSV table, with the file and (for a row) the line.
#[derive(Clone, Debug, PartialEq)]
pub struct CsvError {
    pub path: PathBuf,
    /// 1-based line number, or `None` for a problem of the whole file.
    pub line: Option<usize>,
    /// Boxed so that the error stays small inside the callers' errors.
    pub problem: Box<CsvProblem>,
}

impl fmt::Display for CsvError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{line}: {}", self.path.display(), self.problem),
            None => write!(f, "{}: {}", self.path.display(), self.problem),
        }
    }
}

impl std::error::Error for CsvError {}

/// Non-empty, non-comment lines of `text`, trimmed, with their 1-based line numbers (a leading
/// byte-order mark dropped).
pub fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.strip_prefix('\u{feff}')
        .unwrap_or(text)
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

/// The trimmed cells of one line.
pub fn cells(line: &str) -> Vec<&str> {
    line.split(',').map(str::trim).collect()
}

/// A table's text split into its header and rows, errors naming `path`.
pub struct Table<'a> {
    path: &'a Path,
    header_line: usize,
    header: Vec<&'a str>,
    rows: Vec<Row<'a>>,
}

/// One data row: its line number and trimmed cells.
pub struct Row<'a> {
    pub line: usize,
    pub cells: Vec<&'a str>,
}

impl<'a> Table<'a> {
    /// Splits `text` (read from `path`) into the header row and the data rows. Every row must
    /// have as many cells as the header.
    pub fn parse(text: &'a str, path: &'a Path) -> Result<Self, CsvError> {
        let mut it = lines(text);
        let (header_line, header) = it
            .next()
            .ok_or_else(|| file_error(path, CsvProblem::Empty))?;
        let header = cells(header);
        let mut rows = Vec::new();
        for (line, l) in it {
            let row = cells(l);
            if row.len() != header.len() {
                let problem = CsvProblem::CellCount {
                    got: row.len(),
                    want: header.len(),
                };
                return Err(row_error(path, line, problem));
            }
            rows.push(Row { line, cells: row });
        }
        Ok(Table {
            path,
            header_line,
            header,
            rows,
        })
    }

    /// The header's column names.
    pub fn header(&self) -> &[&'a str] {
        &self.header
    }

    /// The data rows in file order.
    pub fn rows(&self) -> &[Row<'a>] {
        &self.rows
    }

    /// The file the table was read from (for the callers' own row errors).
    pub fn path(&self) -> &Path {
        self.path
    }

    /// The index of column `name` (case-insensitive), or an error on the header's line.
    pub fn column(&self, name: &str) -> Result<usize, CsvError> {
        self.header
            .iter()
            .position(|h| h.eq_ignore_ascii_case(name))
            .ok_or_else(|| {
                let problem = CsvProblem::MissingColumn {
                    name: name.to_string(),
                    have: self.header.join(","),
                };
                row_error(self.path, self.header_line, problem)
            })
    }

    /// The indices of all of `names`, in order.
    pub fn columns(&self, names: &[&str]) -> Result<Vec<usize>, CsvError> {
        names.iter().map(|n| self.column(n)).collect()
    }

    /// Fails with [`CsvProblem::NoRows`] when the table has no data row.
    pub fn require_rows(&self, what: &'static str) -> Result<(), CsvError> {
        if self.rows.is_empty() {
            return Err(file_error(self.path, CsvProblem::NoRows { what }));
        }
        Ok(())
    }

    /// The finite number in `row`'s column `idx`, named `name` in errors.
    pub fn number(&self, row: &Row, idx: usize, name: &str) -> Result<f64, CsvError> {
        number_cell(self.path, row.line, &row.cells, idx, name)
    }

    /// [`Table::number`] parsed straight to `f32`.
    pub fn number_f32(&self, row: &Row, idx: usize, name: &str) -> Result<f32, CsvError> {
        number_cell(self.path, row.line, &row.cells, idx, name)
    }
}

/// The finite number in `cells[idx]` (named `name` in errors) of line `line` of `path`,
/// parsed straight to `T` (`f32` is not rounded through `f64`).
pub fn number_cell<T: std::str::FromStr + Into<f64> + Copy>(
    path: &Path,
    line: usize,
    cells: &[&str],
    idx: usize,
    name: &str,
) -> Result<T, CsvError> {
    let err = |problem| row_error(path, line, problem);
    let cell = cells.get(idx).ok_or_else(|| {
        err(CsvProblem::MissingValue {
            name: name.to_string(),
            cells: cells.len(),
        })
    })?;
    let v: T = cell.parse().map_err(|_| {
        err(CsvProblem::NotNumber {
            name: name.to_string(),
            cell: cell.to_string(),
        })
    })?;
    if !v.into().is_finite() {
        return Err(err(CsvProblem::NotFinite {
            name: name.to_string(),
            cell: cell.to_string(),
        }));
    }
    Ok(v)
}

/// Rows of exactly `N` finite numbers with no named columns (`columns` names them in errors,
/// e.g. `"x,y,z,nx,ny,nz"`); a first row that is not numbers is taken as a header and skipped.
pub fn number_rows<T, const N: usize>(
    text: &str,
    path: &Path,
    columns: &'static str,
) -> Result<Vec<[T; N]>, CsvError>
where
    T: std::str::FromStr + Into<f64> + Copy,
{
    let mut out = Vec::new();
    for (k, (line, l)) in lines(text).enumerate() {
        let vals: Result<Vec<T>, _> = cells(l).iter().map(|c| c.parse::<T>()).collect();
        match vals {
            Ok(v) if v.len() == N && v.iter().all(|x| (*x).into().is_finite()) => {
                out.push(std::array::from_fn(|i| v[i]));
            }
            Err(_) if k == 0 => continue, // the header
            _ => {
                let problem = CsvProblem::NumberRow { want: N, columns };
                return Err(row_error(path, line, problem));
            }
        }
    }
    Ok(out)
}

/// An error of the whole file.
pub fn file_error(path: &Path, problem: CsvProblem) -> CsvError {
    CsvError {
        path: path.to_path_buf(),
        line: None,
        problem: Box::new(problem),
    }
}

/// An error of line `line`.
pub fn row_error(path: &Path, line: usize, problem: CsvProblem) -> CsvError {
    CsvError {
        path: path.to_path_buf(),
        line: Some(line),
        problem: Box::new(problem),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: &str = "t.csv";

    #[test]
    fn header_rows_comments_and_bom() {
        let text = "\u{feff}Name, X ,y\n# note\n\na, 1, 2.5\nb,-3,4e1\n";
        let t = Table::parse(text, Path::new(P)).unwrap();
        assert_eq!(t.header(), ["Name", "X", "y"]);
        assert_eq!(t.columns(&["x", "Y"]).unwrap(), vec![1, 2]);
        let r = &t.rows()[1];
        assert_eq!(r.line, 5);
        assert_eq!(t.number(r, 2, "y").unwrap(), 40.0);
        assert_eq!(t.number(&t.rows()[0], 1, "x").unwrap(), 1.0);
    }

    #[test]
    fn errors_name_the_file_line_and_problem() {
        let e = |text: &str| {
            let t = Table::parse(text, Path::new(P));
            t.and_then(|t| {
                let c = t.column("x")?;
                t.require_rows("rows")?;
                t.rows()
                    .iter()
                    .try_for_each(|r| t.number(r, c, "x").map(drop))
            })
            .unwrap_err()
            .to_string()
        };
        assert_eq!(e("# only\n"), "t.csv: empty file (no header)");
        assert_eq!(
            e("a,b\n1,2\n"),
            "t.csv:1: header lacks column `x` (have: a,b)"
        );
        assert_eq!(e("x,b\n1\n"), "t.csv:2: 1 cells, header has 2");
        assert_eq!(e("x\n"), "t.csv: no rows after the header");
        assert_eq!(e("x\n\nfoo\n"), "t.csv:3: `x` = `foo` is not a number");
        assert_eq!(e("x\nNaN\n"), "t.csv:2: `x` = `NaN` is not finite");
        let short = number_cell::<f64>(Path::new(P), 7, &["1"], 3, "z").unwrap_err();
        assert_eq!(
            short.to_string(),
            "t.csv:7: missing value for `z` (1 cells)"
        );
    }

    #[test]
    fn number_rows_skip_one_header_only() {
        let rows = number_rows::<f64, 2>("u,v\n1,2\n# c\n3, 4\n", Path::new(P), "u,v").unwrap();
        assert_eq!(rows, vec![[1.0, 2.0], [3.0, 4.0]]);
        let e = number_rows::<f64, 2>("1,2\nu,v\n", Path::new(P), "u,v").unwrap_err();
        assert_eq!(e.to_string(), "t.csv:2: expected 2 finite numbers u,v");
        let e = number_rows::<f64, 2>("1,inf\n", Path::new(P), "u,v").unwrap_err();
        assert_eq!(e.line, Some(1));
    }
}
