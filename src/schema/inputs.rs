//! The input tables' contracts: block model, drawpoints, drawbells, periods, schedule, and
//! the production records compared with a run (`caveflow reconcile`, `calibrate`); and
//! MassFlow's fixed column orders.

use super::Kind::*;
use super::{f, ExtraColumns, TableSpec};

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
        f("open_period", I64, "-", "Draw control (strategy = \"target\"): the first period in which the drawpoint may open (its ground must also have caved); empty: once its ground has caved", false, &["OpenPeriod"]),
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

/// Draw control's production target per period (`draw_control.target_table`).
pub const TARGET: TableSpec = TableSpec {
    name: "target",
    description: "Draw control (strategy = \"target\"): the production target of each period, shared among the open drawpoints. A period the table does not list has no target (nothing is drawn in it).",
    fields: &[
        f("period", I64, "-", "Period number (periods.period)", true, &["Period"]),
        f("tonnes", F64, "t", "The period's production target", true, &["Tonnes", "target"]),
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
