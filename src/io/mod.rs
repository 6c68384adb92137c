//! Reading and checking input tables.
//!
//! [`read_table`] reads any [`TableSpec`](crate::schema::TableSpec) from Parquet or
//! delimited text (comma, tab or semicolon; the MassFlow CSV family is matched through the
//! specs' aliases). [`read_schedule`] reads a draw schedule in the long or the MassFlow wide
//! form. Both check every cell and report every problem they find as a [`Problem`] with a
//! stable rule id, never stopping at the first and never panicking on malformed input.
//! Cross-table rules (block grid, joins, physical ranges) live in
//! [`model::load`](crate::model::load).

mod parquet;
mod periods;
mod problem;
mod read;
mod schedule;
mod table;
mod text;
mod trace;

pub use periods::Periods;
pub(crate) use problem::Collector;
pub use problem::{InputWarning, Problem, Problems, KEEP_PER_RULE};
pub(crate) use read::read_table_into;
pub use read::{read_table, read_table_bytes};
pub(crate) use schedule::read_schedule_into;
pub use schedule::{
    parse_period_header, read_schedule, read_schedule_bytes, ScheduleEntry, ScheduleForm,
    ScheduleTable,
};
pub(crate) use table::file_name;
pub use table::{sha256_hex, Column, ExtraColumn, Table};
pub(crate) use trace::read_trace_into;
pub use trace::TracePoints;
