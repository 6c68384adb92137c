//! Atomic file writing and the Parquet writer every table goes through.
//!
//! [`AtomicFile`] writes to `<path>.tmp-<pid>-<n>` in the target's own directory (so the
//! rename never crosses a file system), syncs the data, renames it over the target and
//! syncs the directory. Those last steps are `persist`, which the charts use too (they
//! render to `<stem>.tmp-<pid>-<n>.<ext>` first), so there is one way a file is made final.
//! Until the rename the target is untouched; if the writer is dropped before
//! [`AtomicFile::commit`] (an error, a panic) the temporary file is removed. A hard
//! crash (power loss, `kill -9`) can leave a `*.tmp-*` file beside the target, but never a
//! torn file under the target's name.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use ::parquet::arrow::ArrowWriter;
use ::parquet::basic::{Compression, ZstdLevel};
use ::parquet::file::properties::{EnabledStatistics, WriterProperties};
use arrow::array::ArrayRef;
use arrow::datatypes::Schema;
use arrow::record_batch::RecordBatch;

use super::OutputError;

/// Rows per Parquet row group: large enough for good compression and few footers, small
/// enough that a reader can skip most of a mine-scale table using the statistics.
pub const MAX_ROW_GROUP_ROWS: usize = 1 << 20;

/// Rows per batch when a table is written a part at a time ([`write_batches`]): small,
/// so that memory holds little more than the row group being encoded, and a divisor of
/// [`MAX_ROW_GROUP_ROWS`] and a multiple of the writer's mini-batch of 1024 rows, so that
/// the file is byte for byte the one written from the whole table at once.
pub const PART_ROWS: usize = 1 << 17;

/// zstd level: 3 is zstd's own default, a good balance of speed and size for float columns.
const ZSTD_LEVEL: i32 = 3;

/// Distinguishes temporary files of several writers in one process.
static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> OutputError + '_ {
    move |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// A file that appears under its final name only when [`commit`](Self::commit) succeeds.
///
/// Write to it through [`Write`] (it is buffered). Dropping it without committing removes
/// the temporary file and leaves any previous file at the target untouched.
#[derive(Debug)]
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    out: Option<BufWriter<File>>,
}

impl AtomicFile {
    /// Starts writing `path`: creates the temporary file beside it. The parent directory
    /// must exist.
    pub fn create(path: &Path) -> Result<AtomicFile, OutputError> {
        let name = path.file_name().ok_or_else(|| OutputError::Io {
            path: path.to_path_buf(),
            source: io::Error::new(io::ErrorKind::InvalidInput, "not a file path"),
        })?;
        let mut tmp_name = name.to_os_string();
        tmp_name.push(tmp_tag());
        let tmp = path.with_file_name(tmp_name);
        let file = OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(io_err(&tmp))?;
        Ok(AtomicFile {
            path: path.to_path_buf(),
            tmp,
            out: Some(BufWriter::new(file)),
        })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The temporary file being written.
    pub fn tmp_path(&self) -> &Path {
        &self.tmp
    }

    /// Flushes and syncs the data, renames the temporary file over the target, and syncs the
    /// directory so the rename itself survives a crash.
    pub fn commit(mut self) -> Result<(), OutputError> {
        let out = self.out.take().expect("AtomicFile written after commit");
        let file = out.into_inner().map_err(|e| OutputError::Io {
            path: self.tmp.clone(),
            source: e.into_error(),
        })?;
        let result = persist(file, &self.tmp, &self.path, |path, source| {
            OutputError::Io {
                path: path.to_path_buf(),
                source,
            }
        });
        if result.is_ok() {
            // Renamed: nothing left for Drop to clean up.
            self.tmp = PathBuf::new();
        }
        result
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.out
            .as_mut()
            .expect("AtomicFile written after commit")
            .write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.out
            .as_mut()
            .expect("AtomicFile written after commit")
            .flush()
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        // Close before removing, then remove whatever was not renamed. Errors are moot here:
        // the write already failed and its error is what the caller sees.
        drop(self.out.take());
        if !self.tmp.as_os_str().is_empty() {
            let _ = fs::remove_file(&self.tmp);
        }
    }
}

/// The directory holding `path` ("." for a bare file name).
fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Syncs the directory holding `path`, making a completed rename durable (`persist` calls it
/// after its rename). Directories cannot be opened for syncing on every platform; where
/// they cannot, the rename is still atomic.
fn sync_parent(path: &Path) -> io::Result<()> {
    if cfg!(unix) {
        File::open(parent(path))?.sync_all()?;
    }
    Ok(())
}

/// `.tmp-<pid>-<n>`: the mark of a temporary file, unique within the process (`n` keeps
/// writers and threads apart) and between processes (`pid`).
pub(crate) fn tmp_tag() -> String {
    format!(
        ".tmp-{}-{}",
        std::process::id(),
        TMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    )
}

/// Makes the finished temporary file `tmp` (open as `file`) the file at `path`: syncs its
/// data, closes it, renames it over `path` and syncs the directory. This is the end of every
/// atomic write: [`AtomicFile::commit`], and the charts, which plotters writes to a path
/// itself. `err` turns a failure into the caller's error, given the path it concerns (`tmp`
/// for the sync, `path` for the rename, the directory for its sync). On failure `tmp` is
/// left for the caller to remove.
pub(crate) fn persist<E>(
    file: File,
    tmp: &Path,
    path: &Path,
    err: impl Fn(&Path, io::Error) -> E,
) -> Result<(), E> {
    file.sync_all().map_err(|e| err(tmp, e))?;
    drop(file);
    fs::rename(tmp, path).map_err(|e| err(path, e))?;
    sync_parent(path).map_err(|e| err(parent(path), e))
}

/// Writes `bytes` to `path` atomically (text, JSON, TOML).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Writes `path` atomically from `write`, which streams the contents into the (buffered)
/// temporary file: for contents too large to hold as bytes first, such as a checkpoint
/// (`Engine::write_checkpoint`). An error from `write` leaves the target untouched.
pub fn write_atomic_with(
    path: &Path,
    write: impl FnOnce(&mut AtomicFile) -> io::Result<()>,
) -> Result<(), OutputError> {
    let mut file = AtomicFile::create(path)?;
    write(&mut file).map_err(io_err(path))?;
    file.commit()
}

/// Writer settings shared by every Parquet file: zstd, page-level statistics (min/max per
/// page and per row group, so readers can prune), row groups of at most
/// [`MAX_ROW_GROUP_ROWS`] rows.
fn properties() -> WriterProperties {
    WriterProperties::builder()
        .set_compression(Compression::ZSTD(
            ZstdLevel::try_new(ZSTD_LEVEL).expect("valid zstd level"),
        ))
        .set_statistics_enabled(EnabledStatistics::Page)
        .set_max_row_group_row_count(Some(MAX_ROW_GROUP_ROWS))
        .build()
}

/// Writes one table atomically as Parquet.
///
/// `columns` are moved into a [`RecordBatch`] (build them from owned `Vec`s, e.g.
/// `Float64Array::from(vec)`, and nothing is copied). The schema, with each field's `unit`
/// and `description` metadata, is stored in the file so readers get it back unchanged.
pub fn write_parquet(
    path: &Path,
    schema: Arc<Schema>,
    columns: Vec<ArrayRef>,
) -> Result<(), OutputError> {
    let batch = RecordBatch::try_new(schema, columns).map_err(|source| OutputError::Arrow {
        path: path.to_path_buf(),
        source,
    })?;
    write_batch(path, &batch)
}

/// Writes one record batch atomically as Parquet, its schema (with the fields' `unit` and
/// `description` metadata) stored in the file.
pub fn write_batch(path: &Path, batch: &RecordBatch) -> Result<(), OutputError> {
    write_batches(path, std::iter::once(Ok(batch.clone())))
}

/// Writes one table atomically as Parquet from its rows in consecutive batches, each made
/// only when the writer wants it, so that memory holds one batch and the row group being
/// encoded rather than the whole table. The schema is the first batch's (every batch must
/// have it), and there must be a first batch (it may have no rows). Batches of
/// [`PART_ROWS`] rows give the file [`write_batch`] writes from the whole table, byte for
/// byte.
pub fn write_batches(
    path: &Path,
    mut batches: impl Iterator<Item = Result<RecordBatch, OutputError>>,
) -> Result<(), OutputError> {
    let parquet_err = |source| OutputError::Parquet {
        path: path.to_path_buf(),
        source,
    };
    let first = batches.next().ok_or_else(|| OutputError::Encode {
        path: path.to_path_buf(),
        message: "a table with no batch, not even an empty one".into(),
    })??;
    let mut file = AtomicFile::create(path)?;
    let mut writer =
        ArrowWriter::try_new(&mut file, first.schema(), Some(properties())).map_err(parquet_err)?;
    writer.write(&first).map_err(parquet_err)?;
    drop(first);
    for batch in batches {
        writer.write(&batch?).map_err(parquet_err)?;
    }
    writer.close().map_err(parquet_err)?;
    file.commit()
}
