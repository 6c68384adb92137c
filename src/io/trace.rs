//! Trace points: MassFlow's trace-marker file, a point to follow through the draw per line.
//!
//! # Format
//! Whitespace-separated `x y z` (Easting, Northing, Elevation, m), one point a line, no
//! header, as MassFlow reads it. Also accepted: a UTF-8 byte-order mark, commas or
//! semicolons between the numbers (a CSV export), blank lines and `#` comments (a whole
//! line, or the rest of a line). Rows are numbered by line (comments and blank lines
//! count), so a message's `row 3` is the file's third line; a point's trace id is its
//! place among the points (1, 2, …).
//!
//! # Rules
//! `not-utf8`; `ragged-row` (a line that is not three numbers); `mistyped` (text where a
//! number belongs; a decimal comma is named as such); `not-finite`; `empty-table` (no
//! point at all). Whether a point lies inside the block model is checked where the block
//! model is known (`model::load`, `outside-model`).

use std::path::Path;

use super::problem::{Collector, Problem};
use super::read::read_bytes;
use super::table::{file_name, not_a_number, sha256_hex};

/// The coordinates' names, as messages call the columns.
const AXES: [&str; 3] = ["x", "y", "z"];

/// The points of a trace file, in file order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TracePoints {
    /// File name (last path component), for messages.
    pub file: String,
    /// SHA-256 of the file's bytes.
    pub sha256: String,
    /// Each point, (x, y, z) in m.
    pub points: Vec<[f64; 3]>,
    /// The line (1-based) each point was read from.
    pub rows: Vec<usize>,
}

/// Reads a trace file, every problem into `problems`; None when it could not be read.
pub(crate) fn read_trace_into(path: &Path, problems: &mut Collector) -> Option<TracePoints> {
    let file = file_name(path);
    let bytes = read_bytes(path, &file, problems)?;
    let sha256 = sha256_hex(&bytes);
    Some(TracePoints {
        sha256,
        ..parse_trace(&file, &bytes, problems)
    })
}

/// Parses the text of a trace file (see the module docs).
pub(crate) fn parse_trace(file: &str, bytes: &[u8], problems: &mut Collector) -> TracePoints {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    let mut t = TracePoints {
        file: file.to_string(),
        ..Default::default()
    };
    let before = problems.total();
    for (i, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let row = i + 1;
        let Ok(line) = std::str::from_utf8(line) else {
            problems.push(Problem::at(
                file,
                Some(row),
                None,
                "not-utf8",
                "the line is not UTF-8 text",
            ));
            continue;
        };
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line
            .split(|c: char| c.is_whitespace() || c == ',' || c == ';')
            .filter(|f| !f.is_empty())
            .collect();
        if fields.len() != 3 {
            problems.push(Problem::at(
                file,
                Some(row),
                None,
                "ragged-row",
                format!(
                    "expected three numbers `x y z` (Easting, Northing, Elevation), found {} field(s) in `{line}`",
                    fields.len()
                ),
            ));
            continue;
        }
        let mut p = [0.0; 3];
        let mut ok = true;
        for (a, f) in fields.iter().enumerate() {
            let mut report = |rule, message| {
                problems.push(Problem::at(file, Some(row), Some(AXES[a]), rule, message));
                ok = false;
            };
            match f.parse::<f64>() {
                Ok(x) if x.is_finite() => p[a] = x,
                Ok(x) => report("not-finite", format!("{x} is not a finite number")),
                Err(_) => report("mistyped", not_a_number(f)),
            }
        }
        if ok {
            t.points.push(p);
            t.rows.push(row);
        }
    }
    if t.points.is_empty() && problems.total() == before {
        problems.push(Problem::file(
            file,
            "empty-table",
            "no trace point: expected lines of `x y z`",
        ));
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> (TracePoints, Vec<String>) {
        let mut c = Collector::default();
        let t = parse_trace("trace.txt", text.as_bytes(), &mut c);
        (t, c.finish().0.iter().map(|p| p.to_string()).collect())
    }

    #[test]
    fn points_comments_and_blank_lines() {
        let (t, p) = parse("\u{feff}# x y z\n1 2 3\n\n  4\t5   6  # second\n7,8,9\n");
        assert!(p.is_empty(), "{p:?}");
        assert_eq!(
            t.points,
            [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]
        );
        assert_eq!(t.rows, [2, 4, 5]);
    }

    #[test]
    fn rules() {
        let (t, p) = parse("1 2\n1 2 x\n1,5 2,5 3,5\n1 2 inf\n4 5 6\n");
        assert_eq!(t.points, [[4.0, 5.0, 6.0]]);
        assert_eq!(
            p,
            [
                "trace.txt: row 1: [ragged-row] expected three numbers `x y z` (Easting, Northing, Elevation), found 2 field(s) in `1 2`",
                "trace.txt: row 2, column z: [mistyped] expected a number, found `x`",
                "trace.txt: row 3: [ragged-row] expected three numbers `x y z` (Easting, Northing, Elevation), found 6 field(s) in `1,5 2,5 3,5`",
                "trace.txt: row 4, column z: [not-finite] inf is not a finite number",
            ]
        );
        let (_, p) = parse("# nothing\n\n");
        assert_eq!(
            p,
            ["trace.txt: [empty-table] no trace point: expected lines of `x y z`"]
        );
    }
}
