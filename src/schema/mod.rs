//! Table contracts: one [`TableSpec`] per input and output table.
//!
//! These specs are the single source of truth. `schemas/*.json` is generated from them
//! (`caveflow schema --write schemas/`), a test checks that the committed files match, the
//! readers validate against them, and the Parquet writers attach the same `unit` and
//! `description` metadata to every field.

use std::collections::HashMap;
use std::sync::Arc;

use arrow::datatypes::{DataType, Field, Schema};

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

use Kind::*;

/// Block model: regular, axis-aligned blocks of one size (which may differ per axis).
pub const BLOCK_MODEL: TableSpec = TableSpec {
    name: "block_model",
    description: "One row per block of a regular, axis-aligned block model. Blocks absent from the table are outside the cave.",
    fields: &[
        f("x", F64, "m", "Block centre Easting", true, &["Easting", "XC", "X"]),
        f("y", F64, "m", "Block centre Northing", true, &["Northing", "YC", "Y"]),
        f("z", F64, "m", "Block centre Elevation", true, &["Elevation", "ZC", "Z"]),
        f("block_id", I64, "-", "Unique block identifier", true, &["BlockID", "id"]),
        f("cave_period", I64, "-", "First period in which the block is caved and free to flow (0 = caved before the first period; larger than the schedule = never)", false, &["CavePeriod"]),
        f("cave_period_dyn", I64, "-", "MassFlow CavePeriodDyn: the cave period as MassFlow's dynamic caving updated it; where given and different from cave_period, it is the one used", false, &["CavePeriodDyn"]),
        f("solids_density", F64, "t/m3", "Density of the intact rock solids, rho_s", true, &["SolidsDen", "density"]),
        f("porosity", F64, "-", "In-situ (stagnant caved) porosity n0, a fraction in [0,1)", true, &["InSituPor", "n0"]),
        f("max_porosity", F64, "-", "Dilated porosity n1 inside IMZs (MassFlow MaxPor), a fraction in [n0,1)", true, &["MaxPor", "n1"]),
        f("friction_angle", F64, "deg", "Friction angle phi of the caved material, in (0,90)", true, &["FricAng", "phi"]),
        f("frag_size", F64, "m", "Mean primary fragment diameter d (used when no Weibull parameters are given; otherwise checked against their mean)", false, &["MeanDia", "d50", "dbar"]),
        f("frag_shape", F64, "-", "Weibull shape alpha of primary fragment size (MassFlow PriFragA); s = beta (-ln(1-u))^(1/alpha)", false, &["PriFragA"]),
        f("frag_scale", F64, "m", "Weibull scale beta of primary fragment size (MassFlow PriFragB)", false, &["PriFragB"]),
        f("tensile_strength", F64, "kPa", "Fragment tensile strength sigma_t, used by secondary fragmentation (default 0.1 x UCS; a block with neither does not break)", false, &["TenStr"]),
        f("tensile_shape", F64, "-", "Weibull shape of tensile strength (MassFlow TenStrA)", false, &["TenStrA"]),
        f("tensile_scale", F64, "kPa", "Weibull scale of tensile strength (MassFlow TenStrB)", false, &["TenStrB"]),
        f("ucs", F64, "kPa", "Uniaxial compressive strength of the intact rock", false, &["UCS"]),
        f("perc_k1", F64, "-", "Percolation coefficient k1 (default 11)", false, &["PercK1"]),
        f("perc_k2", F64, "-", "Percolation coefficient k2 (default 4.5)", false, &["PercK2"]),
        f("perc_vmr", F64, "m", "Variance-to-mean ratio of the percolation distance (default 0.5, MassFlow's, for mine-scale fragments; the summary's form is the bed's fragment size d_b, so use d at model scale)", false, &["PercVMR"]),
        f("lithology", Str, "-", "Lithology code", false, &["Lith", "Rocktype", "Lithology"]),
    ],
    extra: Some(ExtraColumns {
        pattern: "<grade name>",
        kind: F64,
        unit: "%",
        description: "Any other numeric column is a grade, in % by mass",
    }),
};

/// Drawpoints.
pub const DRAWPOINTS: TableSpec = TableSpec {
    name: "drawpoints",
    description: "One row per drawpoint: the point of extraction at the base of a drawbell.",
    fields: &[
        f("name", Str, "-", "Unique drawpoint name", true, &["DPName", "drawpoint"]),
        f("x", F64, "m", "Drawpoint Easting (IMZ axis)", true, &["X", "Easting"]),
        f("y", F64, "m", "Drawpoint Northing (IMZ axis)", true, &["Y", "Northing"]),
        f("z", F64, "m", "Drawpoint elevation: base of the IMZ", true, &["Z", "Elevation"]),
        f("drawbell", Str, "-", "Drawbell identifier (joins drawbells.name)", false, &["DBID"]),
        f("bell_type", Str, "-", "Drawbell type", false, &["DBType"]),
        f("width", F64, "m", "Opening width: the diameter of the lowest IMZ disk (default: the drawbell's width, else the scenario default)", false, &["DDWidth"]),
        f("zone", Str, "-", "Reporting zone (e.g. lithology domain) used by reconcile and calibrate", false, &["Zone", "Domain"]),
    ],
    extra: None,
};

/// Drawbells (MassFlow's drawbell file).
pub const DRAWBELLS: TableSpec = TableSpec {
    name: "drawbells",
    description: "One row per drawbell type or drawbell.",
    fields: &[
        f(
            "name",
            Str,
            "-",
            "Drawbell name (joins drawpoints.drawbell or drawpoints.bell_type)",
            true,
            &["BellName"],
        ),
        f(
            "width",
            F64,
            "m",
            "Draw drift width: opening width at the drawpoint",
            true,
            &["DDWidth"],
        ),
        f(
            "height",
            F64,
            "m",
            "Draw drift height",
            false,
            &["DDHeight"],
        ),
    ],
    extra: None,
};

/// Periods.
pub const PERIODS: TableSpec = TableSpec {
    name: "periods",
    description: "One row per schedule period, in order.",
    fields: &[
        f(
            "period",
            I64,
            "-",
            "Period number, strictly increasing (cave_period refers to it)",
            true,
            &["Period", "id"],
        ),
        f(
            "name",
            Str,
            "-",
            "Period name (e.g. Sept-08)",
            false,
            &["Name"],
        ),
        f("days", F64, "d", "Period length", true, &["Days"]),
        f(
            "start_date",
            Str,
            "-",
            "First day of the period, ISO 8601 (YYYY-MM-DD). Optional; an empty cell after the first row follows from the previous period's start and days. Used to map dated production records to periods",
            false,
            &["Start", "StartDate"],
        ),
    ],
    extra: None,
};

/// Draw schedule, long form.
pub const SCHEDULE: TableSpec = TableSpec {
    name: "schedule",
    description: "Long-form draw schedule: tonnes to draw from a drawpoint in a period. The MassFlow wide form (row per drawpoint, column per period) is also read.",
    fields: &[
        f("period", I64, "-", "Period number (periods.period)", true, &["Period"]),
        f("drawpoint", Str, "-", "Drawpoint name (drawpoints.name)", true, &["DPName", "name"]),
        f("tonnes", F64, "t", "Tonnes scheduled", true, &["Tonnes", "mass"]),
    ],
    extra: None,
};

/// Production records for back-analysis.
pub const PRODUCTION: TableSpec = TableSpec {
    name: "production",
    description: "Sampled production per drawpoint and period, for reconcile and calibrate.",
    fields: &[
        f("drawpoint", Str, "-", "Drawpoint name", true, &["DPName"]),
        f(
            "period",
            I64,
            "-",
            "Period number (or give date)",
            false,
            &["Period"],
        ),
        f(
            "date",
            Str,
            "-",
            "Sample date, ISO 8601 (used when period is absent)",
            false,
            &["Date"],
        ),
        f("tonnes", F64, "t", "Tonnes produced", true, &["Tonnes"]),
        f(
            "frag_size",
            F64,
            "m",
            "Sampled mean fragment size",
            false,
            &[],
        ),
    ],
    extra: Some(ExtraColumns {
        pattern: "<grade name>",
        kind: F64,
        unit: "%",
        description: "Sampled grade per grade column of the block model, in % by mass",
    }),
};

/// Extraction report.
pub const EXTRACTION: TableSpec = TableSpec {
    name: "extraction",
    description: "What each drawpoint delivered in each period.",
    fields: &[
        f("drawpoint", Str, "-", "Drawpoint name", true, &[]),
        f("period", I64, "-", "Period number", true, &[]),
        f("scheduled_tonnes", F64, "t", "Tonnes asked for by the schedule in this period", true, &[]),
        f("marker_tonnes", F64, "t", "Mass of the markers drawn in this period", true, &[]),
        f("correction", F64, "-", "Mass correction factor applied to the drawn markers, bounded to [0.1, 2]", true, &[]),
        f("tonnes", F64, "t", "Credited tonnes = correction x marker_tonnes", true, &[]),
        f("shortfall_tonnes", F64, "t", "Scheduled tonnes (plus earlier shortfall) not credited in this period, carried to the next", true, &[]),
        f("cum_tonnes", F64, "t", "Cumulative credited tonnes", true, &[]),
        f("markers", I64, "-", "Number of markers drawn in this period", true, &[]),
        f("dilution", F64, "-", "Mass share of waste (per the scenario's waste rule) in the drawn material (null when no marker was drawn)", false, &[]),
        f("origin_z", F64, "m", "Mass-weighted mean origin elevation of the drawn material (null when no marker was drawn)", false, &[]),
        f("hod", F64, "m", "Height of draw: cumulative tonnes / (column footprint x in-situ bulk density)", true, &[]),
        f("frag_size", F64, "m", "Mass-weighted mean fragment size of the drawn material (null when no marker was drawn)", false, &[]),
        f("fines_share", F64, "-", "Mass share of drawn material finer than the fines cut-off (null when no marker was drawn)", false, &[]),
        f("frag_p20", F64, "m", "Size passed by 20 % of the drawn mass (P20; from the markers' size distributions; null when no marker was drawn)", false, &[]),
        f("frag_p50", F64, "m", "Size passed by 50 % of the drawn mass (P50; null when no marker was drawn)", false, &[]),
        f("frag_p80", F64, "m", "Size passed by 80 % of the drawn mass (P80; null when no marker was drawn)", false, &[]),
        f("fines_origin_z", F64, "m", "Mean origin elevation of the drawn fines (finer than the fines cut-off), weighted by fines mass (null when no fines were drawn)", false, &[]),
        f("fines_waste_share", F64, "-", "Share of the drawn fines that is waste per the scenario's waste rule, e.g. fines from the level above (null when no fines were drawn)", false, &[]),
        f("percolation", F64, "m", "Mass-weighted mean distance the drawn material percolated (fines migration) on its way down, beyond its bulk movement (null when no marker was drawn)", false, &[]),
        f("air_gap", F64, "m3", "Void held under uncaved ground above this drawpoint's IMZ (air gap), released when the ground above caves; void reaching the top of the model is surface subsidence, not air", true, &[]),
        f("rilled_share", F64, "-", "Mass share of the drawn material that rilled on the free surface (null when no marker was drawn)", false, &[]),
        f("rill_distance", F64, "m", "Mass-weighted mean horizontal distance the rilled material rilled (null when none rilled)", false, &[]),
        f("status", Str, "-", "ok | short (could not deliver the schedule) | idle (nothing scheduled)", true, &[]),
        f("short_reason", Str, "-", "Why a short row could not deliver: uncaved (the ground above the drawpoint has not caved) | blocked (its IMZ is held under uncaved ground and has drained into the air gap) | exhausted (its column has run out); empty otherwise", true, &[]),
    ],
    extra: Some(ExtraColumns {
        pattern: "<grade name> | lith_<lithology>",
        kind: F64,
        unit: "% | -",
        description: "Mass-weighted grade of each input grade column (%), then the mass share of each lithology (-); null when no marker was drawn",
    }),
};

/// IMZ geometry.
pub const IMZ: TableSpec = TableSpec {
    name: "imz",
    description: "Disk radii of each drawpoint's IMZ at the end of a period.",
    fields: &[
        f("drawpoint", Str, "-", "Drawpoint name", true, &[]),
        f("period", I64, "-", "Period number", true, &[]),
        f(
            "disk",
            I64,
            "-",
            "Disk index, 0 at the drawpoint",
            true,
            &[],
        ),
        f("z_base", F64, "m", "Disk base elevation", true, &[]),
        f("z_top", F64, "m", "Disk top elevation", true, &[]),
        f("radius", F64, "m", "Disk radius R_i", true, &[]),
    ],
    extra: None,
};

/// Drawn markers (the IEZ).
pub const DRAWN: TableSpec = TableSpec {
    name: "drawn",
    description: "One row per drawn marker: where it came from and who drew it (the IEZ).",
    fields: &[
        f(
            "marker_id",
            I64,
            "-",
            "Marker identifier (lattice site index)",
            true,
            &[],
        ),
        f("drawpoint", Str, "-", "Drawpoint that drew it", true, &[]),
        f(
            "period",
            I64,
            "-",
            "Period in which it was drawn",
            true,
            &[],
        ),
        f("origin_x", F64, "m", "Origin Easting", true, &[]),
        f("origin_y", F64, "m", "Origin Northing", true, &[]),
        f("origin_z", F64, "m", "Origin elevation", true, &[]),
        f("mass", F64, "t", "Marker mass", true, &[]),
        f("block_id", I64, "-", "Block of origin", true, &[]),
        f("frag_size", F64, "m", "Fragment size when drawn", true, &[]),
        f(
            "rill_distance",
            F64,
            "m",
            "Horizontal distance the marker rilled on the free surface (0 if it never rilled)",
            true,
            &[],
        ),
    ],
    extra: None,
};

/// Marker states at chosen periods.
pub const MARKERS: TableSpec = TableSpec {
    name: "markers",
    description: "Every mobilised or drawn marker at the end of a chosen period (markers never mobilised sit at their lattice origin and are not written).",
    fields: &[
        f("marker_id", I64, "-", "Marker identifier (lattice site index)", true, &[]),
        f("period", I64, "-", "Period at whose end the state was taken", true, &[]),
        f("x", F64, "m", "Current Easting", true, &[]),
        f("y", F64, "m", "Current Northing", true, &[]),
        f("z", F64, "m", "Current elevation", true, &[]),
        f("origin_x", F64, "m", "Origin Easting", true, &[]),
        f("origin_y", F64, "m", "Origin Northing", true, &[]),
        f("origin_z", F64, "m", "Origin elevation", true, &[]),
        f("mass", F64, "t", "Marker mass", true, &[]),
        f("block_id", I64, "-", "Block of origin", true, &[]),
        f("state", Str, "-", "in_situ | moving | drawn", true, &[]),
        f("porosity", F64, "-", "Current porosity of the material the marker stands for", true, &[]),
        f("frag_size", F64, "m", "Current representative fragment size", true, &[]),
        f("shear_strain", F64, "-", "Accumulated shear strain Gamma", true, &[]),
        f("shear_work", F64, "kPa", "Accumulated shear work Gamma x sigma_n", true, &[]),
        f("primary_frag_size", F64, "m", "Primary fragment size d0 (sampled from the block's Weibull distribution when fragmentation or fines is on, else the block's mean)", true, &[]),
        f("attrited", F64, "-", "Attrited mass fraction W = K_N (sigma_N Gamma^phi / sigma_t)^beta (secondary fragmentation; K_N, beta, phi from the scenario's [fragmentation] section, whose defaults 1, 1, 0.5 are assumptions)", true, &[]),
        f("percolated", F64, "m", "Accumulated downward percolation distance (fines migration)", true, &[]),
        f("drawpoint", Str, "-", "Drawpoint that drew it (empty if not drawn)", true, &[]),
        f("drawn_period", I64, "-", "Period in which it was drawn (-1 if not drawn)", true, &[]),
    ],
    extra: None,
};

/// Trace points (`--trace`, `inputs.trace`; `engine::trace`).
pub const TRACE: TableSpec = TableSpec {
    name: "trace",
    description: "One row per trace point per period: where each given point is at the period's end, its state, and who drew it when. Trace points carry no mass and change no other output (`engine::trace`).",
    fields: &[
        f("trace_id", I64, "-", "Trace point: its place among the points of the trace file (1, 2, ...)", true, &[]),
        f("period", I64, "-", "Period number", true, &[]),
        f("period_name", Str, "-", "Period name (names may repeat; the number is the identity)", true, &[]),
        f("x", F64, "m", "Easting at the period's end", true, &[]),
        f("y", F64, "m", "Northing at the period's end", true, &[]),
        f("z", F64, "m", "Elevation at the period's end", true, &[]),
        f("origin_x", F64, "m", "Given Easting", true, &[]),
        f("origin_y", F64, "m", "Given Northing", true, &[]),
        f("origin_z", F64, "m", "Given elevation", true, &[]),
        f("state", Str, "-", "in_situ | moving | drawn", true, &[]),
        f("drawpoint", Str, "-", "Drawpoint that drew it (empty if not drawn)", true, &[]),
        f("drawn_period", I64, "-", "Period in which it was drawn (-1 if not drawn)", true, &[]),
        f("shear_strain", F64, "-", "Accumulated shear strain Gamma", true, &[]),
        f("shear_work", F64, "kPa", "Accumulated shear work Gamma x sigma_n", true, &[]),
    ],
    extra: None,
};

/// Stress on sections (summary §5.3, Figs 24–25): one row per grid point per section.
pub const STRESS_SECTIONS: TableSpec = TableSpec {
    name: "stress_sections",
    description: "Stress logic (mechanisms.stress): vertical and horizontal stress on the vertical and horizontal sections at the end of a chosen period, one row per grid point.",
    fields: &[
        f("period", I64, "-", "Period at whose end stress was computed", true, &[]),
        f("section", Str, "-", "Section name: ns_x=<Easting>, ew_y=<Northing> or plan_z=<elevation>", true, &[]),
        f("orientation", Str, "-", "ns (vertical, along Northing) | ew (vertical, along Easting) | plan (horizontal)", true, &[]),
        f("x", F64, "m", "Grid point Easting", true, &[]),
        f("y", F64, "m", "Grid point Northing", true, &[]),
        f("z", F64, "m", "Grid point elevation (slice mid-height)", true, &[]),
        f("sigma_v", F64, "kPa", "Vertical stress carried (null in uncaved ground)", false, &[]),
        f("sigma_h", F64, "kPa", "Horizontal (radial) stress (null in uncaved ground)", false, &[]),
        f("ratio", F64, "-", "Stress:strength ratio of stagnant ground: vertical stress demand over the Mohr-Coulomb strength at the local horizontal stress (1 = yield; null inside IMZs and in uncaved ground)", false, &[]),
        f("zone", Str, "-", "imz | plastic | elastic | far (stagnant, outside every elastic zone) | uncaved", true, &[]),
    ],
    extra: None,
};

/// Stress per level and the interactive-draw flags (summary §5.3).
pub const STRESS_LEVELS: TableSpec = TableSpec {
    name: "stress_levels",
    description: "Stress logic (mechanisms.stress): one row per level (cave slice) at the end of a chosen period, with the flag for potential stress-driven flow of stagnant ground between IMZs (interactive draw).",
    fields: &[
        f("period", I64, "-", "Period at whose end stress was computed", true, &[]),
        f("z", F64, "m", "Level elevation (slice mid-height)", true, &[]),
        f("cave_area", F64, "m2", "Area of flowable (caved) ground in the slice", true, &[]),
        f("cave_perimeter", F64, "m", "Perimeter of the cave slice", true, &[]),
        f("sigma_v_cave", F64, "kPa", "Cave-average vertical stress by Janssen's differential slices (null without caved ground)", false, &[]),
        f("sigma_v_mean", F64, "kPa", "Area-weighted mean of the redistributed vertical stress over the cave slice (equals sigma_v_cave)", false, &[]),
        f("bins", I64, "-", "Bin slices: isolated IMZs or clusters of overlapping IMZs", true, &[]),
        f("groups", I64, "-", "Group slices: bins whose elastic zones overlap", true, &[]),
        f("pillars", I64, "-", "Pillars of stagnant ground between neighbouring bins of one group", true, &[]),
        f("pillar_ratio", F64, "-", "Largest, over the pillars, of the least stress:strength ratio along a pillar (null without pillars)", false, &[]),
        f("stagnant_ratio", F64, "-", "Mean stress:strength ratio of the stagnant ground inside the elastic zones (null without IMZs)", false, &[]),
        f("arched", F64, "kPa", "Force arched onto the stagnant ground (outside the draw area first) to keep the slice average, over the slice area; negative when taken back", true, &[]),
        f("flagged", I64, "-", "1 where a pillar yields along its whole length (potential stress-driven flow: interactive draw), else 0", true, &[]),
    ],
    extra: None,
};

/// Run manifest (JSON, described with the same field conventions).
pub const MANIFEST: TableSpec = TableSpec {
    name: "manifest",
    description: "manifest.json: what was run, on what, and how the mass balanced.",
    fields: &[
        f("caveflow_version", Str, "-", "Crate version", true, &[]),
        f(
            "inputs",
            Str,
            "-",
            "Input files with their SHA-256",
            true,
            &[],
        ),
        f(
            "scenario",
            Str,
            "-",
            "The resolved scenario (every setting, defaults filled in)",
            true,
            &[],
        ),
        f("seed", I64, "-", "Random seed", true, &[]),
        f("wall_time_s", F64, "s", "Wall time of the run", true, &[]),
        f(
            "mass_balance",
            Str,
            "-",
            "Scheduled, credited and shortfall tonnes, overall and per drawpoint; the distribution of the correction factor (rows, median, p10, p90, rows at each bound)",
            true,
            &[],
        ),
        f(
            "warnings",
            Str,
            "-",
            "Warnings raised during the run",
            true,
            &[],
        ),
    ],
    extra: None,
};

/// Air gap per block column and period.
pub const AIR_GAP: TableSpec = TableSpec {
    name: "air_gap",
    description: "Air gap per block column and period: the height of the air blocks (caved, holding less than rilling.air_fill of their in-situ mass; MassFlow: air once 0.75 empty) at the top of each caved stretch of the column, under uncaved ground or open to the top of the model. Only columns with air are listed.",
    fields: &[
        f("period", I64, "-", "Period number", true, &[]),
        f("x", F64, "m", "Block column centre Easting", true, &[]),
        f("y", F64, "m", "Block column centre Northing", true, &[]),
        f("air_gap", F64, "m", "Height of the column's air blocks", true, &[]),
    ],
    extra: None,
};

/// Free-surface height field.
pub const SURFACE: TableSpec = TableSpec {
    name: "surface",
    description: "Free surface (top of the caved material) per marker-lattice column at the chosen periods (outputs.surface_periods; the last by default).",
    fields: &[
        f("period", I64, "-", "Period number", true, &[]),
        f("x", F64, "m", "Column centre Easting", true, &[]),
        f("y", F64, "m", "Column centre Northing", true, &[]),
        f("z", F64, "m", "Top of the caved material in the column", true, &[]),
    ],
    extra: None,
};

/// The speed–accuracy sweep (`caveflow sweep`).
pub const SWEEP: TableSpec = TableSpec {
    name: "sweep",
    description: "One run of the speed–accuracy sweep: a resolution (as multipliers of the scene's default), its wall time, and its errors against the reference (the mean of two runs at two lattice offsets, analysis::sweep).",
    fields: &[
        f("h_mult", F64, "-", "Disk thickness h as a multiple of the default", true, &[]),
        f("spacing_mult", F64, "-", "Marker spacing as a multiple of the default", true, &[]),
        f("increment_mult", F64, "-", "Draw increment as a multiple of the default", true, &[]),
        f("layer_thickness", F64, "m", "Disk thickness h run", true, &[]),
        f("marker_spacing", F64, "m", "Marker spacing run", true, &[]),
        f("draw_increment", F64, "t", "Draw increment run", true, &[]),
        f("max_marker_move", F64, "m", "Largest move of a marker in one of its own steps (engine::cadence); 0: every marker every update, as in the reference", true, &[]),
        f("wall_s", F64, "s", "Wall time of the run (median over the repeats)", true, &[]),
        f("markers", I64, "-", "Markers mobilised", true, &[]),
        f("grade_rmse", F64, "-", "RMSE of the first grade over drawpoint-periods against the reference, divided by the reference's mean grade (0.01 = 1%)", true, &[]),
        f("grade_rmse_late", F64, "-", "grade_rmse over the drawpoint-periods of the second half of the schedule's periods", true, &[]),
        f("dilution_entry_error", F64, "-", "Mean relative error over drawpoints of the dilution entry: the cumulative tonnes at which a period's waste share first reaches 10%", true, &[]),
        f("imz_width_error", F64, "-", "Mean relative error over drawpoints of the widest IMZ disk (2 R) at the last period", true, &[]),
        f("iez_height_error", F64, "-", "Mean relative error over drawpoints of the IEZ height (95th percentile of drawn origin heights above the drawpoint)", true, &[]),
        f("delivered", F64, "-", "Credited / scheduled tonnes", true, &[]),
        f("is_default", I64, "-", "1 for the default resolution", true, &[]),
        f("is_reference", I64, "-", "1 for the reference; its error columns hold its own error: the noise measured between its two runs and the bias its check leaves unexplained (analysis::sweep)", true, &[]),
        f("is_reference_check", I64, "-", "1 for the check at twice the reference's h and spacing (two runs, like the reference) that bounds the reference's bias", true, &[]),
        f("pareto", I64, "-", "1 when no other run is both faster and has a smaller grade_rmse", true, &[]),
        f("is_auto", I64, "-", "1 for the automatic resolution chosen for the sweep's accuracy target (engine::resolution)", true, &[]),
    ],
    extra: None,
};

/// One variant of a scenario study (`caveflow study`, `summary.parquet`).
pub const STUDY_SUMMARY: TableSpec = TableSpec {
    name: "study_summary",
    description: "One variant of a scenario study: its identity, what it drew, at what grade, how much of the footprint's metal, when dilution entered, how often drawpoints fell short, and its run time (analysis::study).",
    fields: &[
        f("variant", Str, "-", "Variant name: the scenario= partition of the study's dataset", true, &[]),
        f("hash", Str, "-", "Content hash of the variant (SHA-256 of the resolved scenario, the input files' SHA-256 and the seed), as in its _SUCCESS file", true, &[]),
        f("seed", I64, "-", "Seed of the run", true, &[]),
        f("tonnes", F64, "t", "Credited tonnes over the run", true, &[]),
        f("scheduled_tonnes", F64, "t", "Tonnes the schedule asked for", true, &[]),
        f("footprint_tonnes", F64, "t", "In-situ tonnes of the footprint: the block columns whose centre lies within s/sqrt(2) of a drawpoint axis (s the median distance between neighbouring drawpoints), from the lowest drawpoint up", true, &[]),
        f("dilution_entry", F64, "t", "Mean over the drawpoints whose waste share reaches 10% of the cumulative tonnes at which it does (null when none does)", false, &[]),
        f("diluted_drawpoints", I64, "-", "Drawpoints whose waste share reached 10%", true, &[]),
        f("short_share", F64, "-", "Share of the scheduled (not idle) drawpoint-periods that were short", false, &[]),
        f("periods", I64, "-", "Periods run", true, &[]),
        f("wall_s", F64, "s", "Wall time of the engine run", true, &[]),
    ],
    extra: Some(ExtraColumns {
        pattern: "<grid key> | <alternative dimension> | <grade name> | recovery_<grade name>",
        kind: F64,
        unit: "- | - | % | -",
        description: "The swept value of each grid key (Float64 when every value is a number, else Utf8) and the alternative chosen in each dimension (Utf8); then the tonnage-weighted mean grade of everything drawn (%), then the metal drawn over the metal in situ in the footprint (-; above 1 when the draw reaches beyond the footprint, as it does where neighbouring ground or broken material above feeds the drawpoints)",
    }),
};

/// Reconciliation metrics (`caveflow reconcile`).
pub const RECONCILE_METRICS: TableSpec = TableSpec {
    name: "reconcile",
    description: "Predicted against sampled grades: error statistics per drawpoint, per zone and overall, per grade. Error e = predicted − sampled.",
    fields: &[
        f("level", Str, "-", "drawpoint | zone | overall", true, &[]),
        f("key", Str, "-", "Drawpoint name, zone name, or all", true, &[]),
        f("grade", Str, "-", "Grade column compared", true, &[]),
        f("n", I64, "-", "Drawpoint-periods compared", true, &[]),
        f("bias", F64, "%", "Mean error", true, &[]),
        f("mae", F64, "%", "Mean absolute error", true, &[]),
        f("rmse", F64, "%", "Root mean square error", true, &[]),
        f("correlation", F64, "-", "Pearson correlation of predicted and sampled grades (null below 2 rows)", true, &[]),
        f("tw_error", F64, "%", "Tonnage-weighted error: sum of sampled tonnes × error over sum of sampled tonnes", true, &[]),
        f("mean_predicted", F64, "%", "Mean predicted grade", true, &[]),
        f("mean_sampled", F64, "%", "Mean sampled grade", true, &[]),
        f("sampled_tonnes", F64, "t", "Tonnes of the records compared", true, &[]),
        f("de_predicted", F64, "t", "Dilution entry predicted: cumulative tonnes at which the dilution grade first falls below the cutoff (zones and overall: mean over drawpoints where both are known)", false, &[]),
        f("de_sampled", F64, "t", "Dilution entry sampled, as de_predicted", false, &[]),
        f("de_difference", F64, "t", "de_predicted − de_sampled (negative: the model dilutes too early)", false, &[]),
    ],
    extra: None,
};

/// Matched prediction and record rows (`caveflow reconcile`).
pub const RECONCILE_ROWS: TableSpec = TableSpec {
    name: "reconcile_rows",
    description: "One row per drawpoint, period and grade where a prediction and a record meet.",
    fields: &[
        f("drawpoint", Str, "-", "Drawpoint name", true, &[]),
        f(
            "zone",
            Str,
            "-",
            "Drawpoint zone (empty when not given)",
            true,
            &[],
        ),
        f("x", F64, "m", "Drawpoint Easting", true, &[]),
        f("y", F64, "m", "Drawpoint Northing", true, &[]),
        f("period", I64, "-", "Period number", true, &[]),
        f(
            "cum_tonnes",
            F64,
            "t",
            "Predicted cumulative tonnes at the end of the period",
            true,
            &[],
        ),
        f(
            "predicted_tonnes",
            F64,
            "t",
            "Credited tonnes of the period",
            true,
            &[],
        ),
        f(
            "sampled_tonnes",
            F64,
            "t",
            "Tonnes of the records matched to the period",
            true,
            &[],
        ),
        f("grade", Str, "-", "Grade column", true, &[]),
        f("predicted", F64, "%", "Predicted grade", true, &[]),
        f(
            "sampled",
            F64,
            "%",
            "Sampled grade (tonnage-weighted over the matched records)",
            true,
            &[],
        ),
        f("error", F64, "%", "predicted − sampled", true, &[]),
    ],
    extra: None,
};

/// Every table, for `caveflow schema`.
pub const ALL: &[TableSpec] = &[
    BLOCK_MODEL,
    DRAWPOINTS,
    DRAWBELLS,
    PERIODS,
    SCHEDULE,
    PRODUCTION,
    RECONCILE_METRICS,
    RECONCILE_ROWS,
    EXTRACTION,
    IMZ,
    DRAWN,
    MARKERS,
    TRACE,
    AIR_GAP,
    SURFACE,
    STRESS_SECTIONS,
    STRESS_LEVELS,
    MANIFEST,
    SWEEP,
    STUDY_SUMMARY,
];

/// The drawpoint file's columns in MassFlow's fixed order (`TableSpec::massflow_layout`).
pub const MASSFLOW_DRAWPOINTS: &[&str] = &["DPName", "X", "Y", "Z", "DBID", "DBType"];

/// The drawbell file's 14 documented columns in MassFlow's fixed order.
pub const MASSFLOW_DRAWBELLS: &[&str] = &[
    "BellName",
    "DDWidth",
    "DDHeight",
    "BellHeight",
    "SideAngle",
    "EndAngle",
    "DFZDepth",
    "DFZWidth",
    "DFZHeight",
    "SideHoleAngle",
    "CrossCutSpacing",
    "SublevelSpacing",
    "Burden",
    "RetreatAz",
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
