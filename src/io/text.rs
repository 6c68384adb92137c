//! Delimited text (CSV, TSV, semicolon-separated): the low-level scan shared by the table
//! reader and the MassFlow wide schedule reader.
//!
//! # What is accepted
//! - A UTF-8 byte-order mark is stripped.
//! - The delimiter is whichever of comma, tab and semicolon occurs most often (outside
//!   quotes) in the header line; ties prefer comma, then tab.
//! - Fields may be quoted (`"1.5"` is the number 1.5); surrounding whitespace is trimmed.
//! - Blank lines are dropped. Lines whose fields are all empty (the `,,,,` rows
//!   spreadsheets leave behind) are skipped with a warning; they still count in row
//!   numbers, so a message's `row 12` is the 12th record after the header.
//! - Every other row must have as many fields as the header (`ragged-row`) and be valid
//!   UTF-8 (`not-utf8`).
//! - A header of one field that splits on a pipe, a colon or spaces is `wrong-delimiter`
//!   (every table has two columns or more), and the file is not read further.
//! - MassFlow's preamble, a first line `Delimiter: <anything>;` ahead of the header (its
//!   tab-delimited example projects begin with `Delimiter: r;`), is skipped; the delimiter
//!   is still detected from the header. A first line whose first word is `Delimiter` but
//!   that is not of that form (`Delimiter r`, `Delimiter: r` without the `;`) is
//!   `delimiter-line`, and the file is not read further.

use csv::{ByteRecord, ReaderBuilder, Trim};

use super::problem::{Collector, Problem};
use super::table::Cell;

/// The bytes of one delimited text file, BOM stripped, delimiter detected.
pub(crate) struct Text {
    /// File name for messages.
    pub file: String,
    bytes: Vec<u8>,
    delimiter: u8,
    /// A first line that looks like MassFlow's `Delimiter: …;` preamble but is not one.
    bad_preamble: Option<String>,
}

impl Text {
    /// Wraps a file's bytes.
    pub(crate) fn new(file: &str, mut bytes: Vec<u8>) -> Text {
        if bytes.starts_with(b"\xEF\xBB\xBF") {
            bytes.drain(..3);
        }
        let mut bad_preamble = None;
        match preamble(&bytes) {
            Preamble::None => {}
            Preamble::Valid(len) => {
                bytes.drain(..len);
            }
            Preamble::Invalid(line) => {
                bad_preamble = Some(match line.char_indices().nth(60) {
                    Some((i, _)) => format!("{}…", &line[..i]),
                    None => line,
                })
            }
        }
        let delimiter = detect_delimiter(&bytes);
        Text {
            file: file.to_string(),
            bytes,
            delimiter,
            bad_preamble,
        }
    }

    fn reader(&self) -> csv::Reader<&[u8]> {
        ReaderBuilder::new()
            .delimiter(self.delimiter)
            .has_headers(false)
            .flexible(true)
            .trim(Trim::All)
            .from_reader(&self.bytes[..])
    }

    /// The header names, trimmed. None (with an `empty-table` problem) when the file holds
    /// no header line at all.
    pub(crate) fn headers(&self, problems: &mut Collector) -> Option<Vec<String>> {
        if let Some(line) = &self.bad_preamble {
            let message = format!(
                "the first line `{line}` starts like MassFlow's delimiter line but is not one: it must read `Delimiter: <delimiter>;` (a colon after Delimiter, a semicolon at the end), or be removed so that the header comes first"
            );
            problems.push(Problem::file(&self.file, "delimiter-line", message));
            return None;
        }
        let mut rec = ByteRecord::new();
        match self.reader().read_byte_record(&mut rec) {
            Ok(true) => {}
            Ok(false) => {
                let message = "the file is empty: no header, no rows";
                problems.push(Problem::file(&self.file, "empty-table", message));
                return None;
            }
            Err(e) => {
                let message = format!("cannot read the header: {e}");
                problems.push(Problem::file(&self.file, "unreadable", message));
                return None;
            }
        }
        let mut names = Vec::with_capacity(rec.len());
        for (i, field) in rec.iter().enumerate() {
            match std::str::from_utf8(field) {
                Ok(s) => names.push(s.to_string()),
                Err(_) => {
                    let lossy = String::from_utf8_lossy(field).into_owned();
                    problems.push(Problem::at(
                        &self.file,
                        Some(0),
                        Some(&lossy),
                        "not-utf8",
                        format!(
                            "header field {} is not valid UTF-8; save the file as UTF-8",
                            i + 1
                        ),
                    ));
                    names.push(lossy);
                }
            }
        }
        if let [only] = &names[..] {
            if let Some(sep) = foreign_delimiter(only) {
                let message = format!(
                    "the header is one single column, `{only}`: the file seems to be separated by {sep}; caveflow reads comma-, tab- or semicolon-separated text (export it again as CSV)"
                );
                problems.push(Problem::at(
                    &self.file,
                    Some(0),
                    None,
                    "wrong-delimiter",
                    message,
                ));
                return None;
            }
        }
        Some(names)
    }

    /// Calls `visit(row, cells, problems)` for every data row, with `row` counted from 1.
    /// Ragged rows and all-empty rows are not visited. Returns the number of data rows
    /// (including skipped ones) and the numbers of the skipped empty rows.
    pub(crate) fn rows(
        &self,
        headers: &[String],
        problems: &mut Collector,
        mut visit: impl FnMut(usize, &[Cell<'_>], &mut Collector),
    ) -> (usize, Vec<usize>) {
        let mut reader = self.reader();
        let mut rec = ByteRecord::new();
        let mut row = 0usize;
        let mut skipped = Vec::new();
        let mut first = true;
        loop {
            match reader.read_byte_record(&mut rec) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => {
                    let p =
                        Problem::at(&self.file, Some(row + 1), None, "unreadable", e.to_string());
                    problems.push(p);
                    break;
                }
            }
            if first {
                first = false;
                continue;
            }
            row += 1;
            if rec.iter().all(|f| f.is_empty()) {
                skipped.push(row);
                continue;
            }
            if rec.len() != headers.len() {
                problems.push(Problem::at(
                    &self.file,
                    Some(row),
                    None,
                    "ragged-row",
                    format!(
                        "the row has {} fields but the header has {}{}",
                        rec.len(),
                        headers.len(),
                        self.other_delimiter(&rec)
                    ),
                ));
                continue;
            }
            let mut cells = Vec::with_capacity(headers.len());
            for (field, name) in rec.iter().zip(headers) {
                cells.push(match std::str::from_utf8(field) {
                    Ok("") => Cell::Null,
                    Ok(s) => Cell::Text(s),
                    Err(_) => {
                        problems.push(Problem::at(
                            &self.file,
                            Some(row),
                            Some(name),
                            "not-utf8",
                            format!(
                                "the value `{}` is not valid UTF-8; save the file as UTF-8",
                                String::from_utf8_lossy(field)
                            ),
                        ));
                        Cell::Invalid
                    }
                });
            }
            visit(row, &cells, problems);
        }
        (row, skipped)
    }
}

impl Text {
    /// A hint for a ragged row that is one field holding another delimiter: the rows were
    /// written with a different separator than the header.
    fn other_delimiter(&self, rec: &ByteRecord) -> String {
        let Some(field) = rec.get(0).filter(|_| rec.len() == 1) else {
            return String::new();
        };
        [(b',', "a comma"), (b'\t', "a tab"), (b';', "a semicolon")]
            .iter()
            .filter(|(d, _)| *d != self.delimiter && field.contains(d))
            .map(|(_, name)| {
                format!(
                    " (the row seems separated by {name}, the header by {})",
                    name_of(self.delimiter)
                )
            })
            .next()
            .unwrap_or_default()
    }
}

/// How a message names a delimiter.
fn name_of(d: u8) -> &'static str {
    match d {
        b'\t' => "a tab",
        b';' => "a semicolon",
        _ => "a comma",
    }
}

/// The separator a one-field header seems to use instead of comma, tab or semicolon: a
/// pipe, a colon, or runs of spaces between names. Every table has at least two columns,
/// so a one-field header that splits on one of these was exported with the wrong
/// delimiter.
fn foreign_delimiter(header: &str) -> Option<&'static str> {
    if header.contains('|') {
        Some("`|`")
    } else if header.contains(':') {
        Some("`:`")
    } else if header.split_whitespace().count() > 1 {
        Some("spaces")
    } else {
        None
    }
}

/// What the first line of a file is, as far as MassFlow's `Delimiter: …;` preamble goes.
#[derive(Debug, PartialEq)]
enum Preamble {
    /// An ordinary first line (the header).
    None,
    /// A delimiter line, this many bytes long with its line break.
    Valid(usize),
    /// A first line whose first word is `Delimiter` but that is not `Delimiter: …;`.
    Invalid(String),
}

/// Recognises MassFlow's preamble line `Delimiter: <any text>;` (the word case-insensitive,
/// spaces allowed around the colon and after the semicolon).
fn preamble(bytes: &[u8]) -> Preamble {
    const WORD: &[u8] = b"delimiter";
    let end = bytes
        .iter()
        .position(|&b| b == b'\n')
        .map_or(bytes.len(), |i| i + 1);
    let line = &bytes[..end];
    let text = String::from_utf8_lossy(line);
    let trimmed = text.trim();
    let starts = trimmed.len() >= WORD.len()
        && trimmed.as_bytes()[..WORD.len()].eq_ignore_ascii_case(WORD)
        && !trimmed[WORD.len()..].starts_with(|c: char| c.is_ascii_alphanumeric() || c == '_');
    if !starts {
        return Preamble::None;
    }
    let rest = trimmed[WORD.len()..].trim_start();
    if rest.starts_with(':') && rest.len() > 1 && rest.ends_with(';') {
        Preamble::Valid(end)
    } else {
        Preamble::Invalid(trimmed.to_string())
    }
}

/// Comma, tab or semicolon: whichever occurs most in the first line outside quotes.
fn detect_delimiter(bytes: &[u8]) -> u8 {
    let mut counts = [0usize; 3];
    let mut quoted = false;
    for &b in bytes {
        match b {
            b'"' => quoted = !quoted,
            b'\n' | b'\r' if !quoted => break,
            b',' if !quoted => counts[0] += 1,
            b'\t' if !quoted => counts[1] += 1,
            b';' if !quoted => counts[2] += 1,
            _ => {}
        }
    }
    let delimiters = [b',', b'\t', b';'];
    let mut best = 0;
    for i in 1..3 {
        if counts[i] > counts[best] {
            best = i;
        }
    }
    delimiters[best]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preamble_lines() {
        assert_eq!(preamble(b"Delimiter: r;\nA\tB\n"), Preamble::Valid(14));
        assert_eq!(preamble(b"delimiter :\t; \r\nA\tB\n"), Preamble::Valid(16));
        assert_eq!(preamble(b"Delimiter:;"), Preamble::Valid(11));
        assert_eq!(preamble(b"x,y\n"), Preamble::None);
        assert_eq!(preamble(b"DelimiterX,y\n"), Preamble::None);
        assert_eq!(
            preamble(b"Delimiter r\nA\n"),
            Preamble::Invalid("Delimiter r".into())
        );
        assert_eq!(
            preamble(b"Delimiter: r\nA\n"),
            Preamble::Invalid("Delimiter: r".into())
        );
        assert_eq!(
            preamble(b"Delimiter"),
            Preamble::Invalid("Delimiter".into())
        );
    }
}
