//! Table contracts: one [`TableSpec`] per input and output table.
//!
//! These specs are the single source of truth. `schemas/*.json` is generated from them
//! (`caveflow schema --write schemas/`), a test checks that the committed files match, the
//! readers validate against them, and the Parquet writers attach the same `unit` and
//! `description` metadata to every field.
//!
//! The specs by side: [`inputs`] (the tables a run reads, and the production records) and
//! [`outputs`] (the tables runs, sweeps, studies and reconciliations write); every one is
//! also here, as `schema::BLOCK_MODEL` etc.

use std::collections::HashMap;
use std::sync::Arc;

use arrow::datatypes::{DataType, Field, Schema};

pub mod inputs;
pub mod outputs;

pub use inputs::*;
pub use outputs::*;

/// Logical column type of a field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// 64-bit float.
    F64,
    /// 64-bit signed integer.
    I64,
    /// 32-bit unsigned integer.
    U32,
    /// UTF-8 text.
    Str,
}

impl Kind {
    /// The Arrow type written for this kind.
    pub fn arrow(self) -> DataType {
        match self {
            Kind::F64 => DataType::Float64,
            Kind::I64 => DataType::Int64,
            Kind::U32 => DataType::UInt32,
            Kind::Str => DataType::Utf8,
        }
    }
    /// Name used in the JSON schemas and error messages.
    pub fn name(self) -> &'static str {
        match self {
            Kind::F64 => "Float64",
            Kind::I64 => "Int64",
            Kind::U32 => "UInt32",
            Kind::Str => "Utf8",
        }
    }
}

/// One column of a table.
#[derive(Debug, Clone, Copy)]
pub struct FieldSpec {
    /// Canonical snake_case name.
    pub name: &'static str,
    /// Column type.
    pub kind: Kind,
    /// SI unit, or "-" for dimensionless / identifiers.
    pub unit: &'static str,
    /// What the column means.
    pub description: &'static str,
    /// Whether a reader must find it.
    pub required: bool,
    /// Other accepted header names (MassFlow names first), matched case-insensitively.
    pub aliases: &'static [&'static str],
}

/// Columns beyond the fixed ones (grades, lithology shares).
#[derive(Debug, Clone, Copy)]
pub struct ExtraColumns {
    /// How extra column names are formed.
    pub pattern: &'static str,
    /// Their type.
    pub kind: Kind,
    /// Their unit.
    pub unit: &'static str,
    /// What they mean.
    pub description: &'static str,
}

/// A table contract.
#[derive(Debug, Clone, Copy)]
pub struct TableSpec {
    /// Table name as used by `caveflow schema <table>`.
    pub name: &'static str,
    /// What one row is.
    pub description: &'static str,
    /// The fixed fields, in output order.
    pub fields: &'static [FieldSpec],
    /// Variable columns, if the table has them.
    pub extra: Option<ExtraColumns>,
}

/// A field spec, briefly (the tables' field lists are written with it).
const fn f(
    name: &'static str,
    kind: Kind,
    unit: &'static str,
    description: &'static str,
    required: bool,
    aliases: &'static [&'static str],
) -> FieldSpec {
    FieldSpec {
        name,
        kind,
        unit,
        description,
        required,
        aliases,
    }
}

/// Every table, for `caveflow schema`.
pub const ALL: &[TableSpec] = &[
    BLOCK_MODEL,
    DRAWPOINTS,
    DRAWBELLS,
    PERIODS,
    SCHEDULE,
    TARGET,
    PRODUCTION,
    RECONCILE_METRICS,
    RECONCILE_ROWS,
    EXTRACTION,
    IMZ,
    DRAWN,
    MARKERS,
    TRACE,
    CLOSURES,
    PRODUCTION_TARGET,
    VALUE,
    BEST_HOD,
    AIR_GAP,
    SURFACE,
    STRESS_SECTIONS,
    STRESS_LEVELS,
    MANIFEST,
    SWEEP,
    STUDY_SUMMARY,
];

/// Look a table up by name.
pub fn table(name: &str) -> Option<&'static TableSpec> {
    ALL.iter().find(|t| t.name == name)
}

impl TableSpec {
    /// The fixed field of this name.
    pub fn field(&self, name: &str) -> Option<&'static FieldSpec> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// Arrow schema with unit/description metadata; `extra` names the variable columns
    /// (all of the extra kind), appended after the fixed fields in `order` if given.
    pub fn arrow_schema(&self, fixed: &[&str], extra: &[String]) -> Arc<Schema> {
        let mut fields: Vec<Field> = Vec::new();
        for name in fixed {
            let spec = self
                .field(name)
                .unwrap_or_else(|| panic!("{} has no field {name}", self.name));
            fields.push(arrow_field(
                spec.name,
                spec.kind,
                spec.unit,
                spec.description,
                !spec.required,
            ));
        }
        if let Some(x) = &self.extra {
            for name in extra {
                let (unit, desc) = if name.starts_with("lith_") {
                    ("-", "Mass share of this lithology")
                } else {
                    (x.unit.split(" | ").next().unwrap_or(x.unit), x.description)
                };
                fields.push(arrow_field(name, x.kind, unit, desc, true));
            }
        }
        Arc::new(Schema::new(fields).with_metadata(HashMap::from([(
            "description".to_string(),
            self.description.to_string(),
        )])))
    }

    /// Documented MassFlow columns of this table that caveflow recognises but does not
    /// use: the readers skip them with one note per file (not one warning per column, and
    /// never as grades). The drawbell geometry beyond the opening (the engine's IMZ starts
    /// at the drawpoint), and the block model's columns MassFlow computes itself.
    pub fn massflow_unused(&self) -> &'static [&'static str] {
        match self.name {
            "block_model" => &["MeanDiaDyn", "SDDia", "Pmin", "Kexp"],
            "drawbells" => &MASSFLOW_DRAWBELLS[3..],
            _ => &[],
        }
    }

    /// MassFlow's fixed column order for this table, where MassFlow reads it by position
    /// (its header strings are not significant): a file with this many columns and headers
    /// that are not all recognised is read by position.
    pub fn massflow_layout(&self) -> Option<&'static [&'static str]> {
        match self.name {
            "drawpoints" => Some(MASSFLOW_DRAWPOINTS),
            "drawbells" => Some(MASSFLOW_DRAWBELLS),
            _ => None,
        }
    }

    /// Names of all fixed fields.
    pub fn field_names(&self) -> Vec<&'static str> {
        self.fields.iter().map(|f| f.name).collect()
    }

    /// The JSON form written to `schemas/<name>.json`.
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        let fields: Vec<_> = self
            .fields
            .iter()
            .map(|f| {
                json!({
                    "name": f.name,
                    "type": f.kind.name(),
                    "nullable": !f.required,
                    "required": f.required,
                    "metadata": {"unit": f.unit, "description": f.description},
                    "aliases": f.aliases,
                })
            })
            .collect();
        let mut v = json!({
            "table": self.name,
            "description": self.description,
            "fields": fields,
        });
        if let Some(x) = &self.extra {
            v["extra_columns"] = json!({
                "pattern": x.pattern,
                "type": x.kind.name(),
                "metadata": {"unit": x.unit, "description": x.description},
            });
        }
        v
    }
}

/// One Arrow field with `unit` and `description` metadata.
pub fn arrow_field(name: &str, kind: Kind, unit: &str, description: &str, nullable: bool) -> Field {
    Field::new(name, kind.arrow(), nullable).with_metadata(HashMap::from([
        ("unit".to_string(), unit.to_string()),
        ("description".to_string(), description.to_string()),
    ]))
}
