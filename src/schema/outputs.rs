//! The output tables' contracts: what a run writes (extraction, IMZ, drawn, markers, trace,
//! stress, air gap, surface, manifest), and what a sweep, a study and a reconciliation
//! write.

use super::Kind::*;
use super::{f, ExtraColumns, TableSpec};

/// Extraction report.
pub const EXTRACTION: TableSpec = TableSpec {
    name: "extraction",
    description: "What each drawpoint delivered in each period.",
    fields: &[
        f("drawpoint", Str, "-", "Drawpoint name", true, &[]),
        f("period", I64, "-", "Period number", true, &[]),
        f("scheduled_tonnes", F64, "t", "Tonnes asked for by the schedule in this period", true, &[]),
        f("marker_tonnes", F64, "t", "Mass of the markers drawn in this period", true, &[]),
        f("correction", F64, "-", "Credited over marker tonnes, a diagnostic of the markers' discreteness (NaN when no marker was drawn)", true, &[]),
        f("tonnes", F64, "t", "Credited tonnes: the scheduled tonnes while the drawpoint's lowest disks can feed them (fill at least 0.726), else by its markers: the schedule while they keep up with it to within their discreteness, else what they weigh (short)", true, &[]),
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
        f("short_reason", Str, "-", "Why a short row could not deliver: uncaved (the ground above the drawpoint has not caved) | blocked (fill below 0.726 under an air gap: its column has drained into the air gap under uncaved ground) | exhausted (fill below 0.726, no air gap: its column is drawn out); empty otherwise. A drawpoint whose fill is at least 0.726 is credited its schedule and is not short", true, &[]),
        f("fill", F64, "-", "Fill of the drawpoint's lowest disks at the end of the period: the volume at the dilated porosity n1 of the markers inside them over the disks' volume, over the lowest disks that hold the period's schedule and 120 markers (about 0.97 where the column is full; below 0.726 it is running out). Null where it did not draw or its IMZ is still smaller than that", false, &[]),
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

/// Draw control's closures (`[draw_control]`, `engine::draw_control`).
pub const CLOSURES: TableSpec = TableSpec {
    name: "closures",
    description: "Draw control (strategy = \"target\"): one row per drawpoint closed by a closure rule, in the period its rule was first met; it draws nothing after it.",
    fields: &[
        f("drawpoint", Str, "-", "Drawpoint name", true, &[]),
        f("period", I64, "-", "Period in which it closed (its last period of draw)", true, &[]),
        f("reason", Str, "-", "shutoff_grade | dilution | hod_limit | best_hod | exhausted", true, &[]),
        f("cum_tonnes", F64, "t", "Tonnes it drew in all", true, &[]),
        f("hod", F64, "m", "Height of draw at closure", true, &[]),
        f("grade", F64, "grade units", "Grade of what it drew in the closing period, as known then: the shut-off column, else the first grade column", true, &[]),
    ],
    extra: None,
};

/// Draw control's production against target (`engine::draw_control`).
pub const PRODUCTION_TARGET: TableSpec = TableSpec {
    name: "production_target",
    description: "Draw control (strategy = \"target\"): per period, the production target, the tonnes shared among the open drawpoints, the tonnes credited, and what no open drawpoint could take.",
    fields: &[
        f("period", I64, "-", "Period number", true, &[]),
        f("target_tonnes", F64, "t", "Target: target_rate x the period's days, or the target table's row", true, &[]),
        f("planned_tonnes", F64, "t", "Tonnes shared among the open drawpoints (the realised schedule's period total)", true, &[]),
        f("tonnes", F64, "t", "Tonnes credited (below planned where a drawpoint could not deliver its share)", true, &[]),
        f("shortfall_tonnes", F64, "t", "Target no open drawpoint could take under its rate limit", true, &[]),
        f("open", I64, "-", "Drawpoints open in the period", true, &[]),
        f("held", I64, "-", "Drawpoints held in the period because their IMZ holds an air gap under ground not yet caved (not open)", true, &[]),
        f("closed", I64, "-", "Drawpoints closed before the period", true, &[]),
    ],
    extra: None,
};

/// Values per drawpoint-period (`[economics]`, `engine::value`).
pub const VALUE: TableSpec = TableSpec {
    name: "value",
    description: "With [economics]: what each drawpoint-period's draw was worth, tonnes x (sum of price x grade x recovery - cost per tonne), and the drawpoint's cumulative value: its value curve along the height of draw.",
    fields: &[
        f("drawpoint", Str, "-", "Drawpoint name", true, &[]),
        f("period", I64, "-", "Period number", true, &[]),
        f("tonnes", F64, "t", "Credited tonnes", true, &[]),
        f("hod", F64, "m", "Height of draw at the period's end", true, &[]),
        f("value", F64, "currency", "The period's value", true, &[]),
        f("cum_value", F64, "currency", "Cumulative value at the period's end", true, &[]),
    ],
    extra: None,
};

/// Best height of draw per drawpoint (`[economics]`, `engine::value`).
pub const BEST_HOD: TableSpec = TableSpec {
    name: "best_hod",
    description: "With [economics]: per drawpoint, the height of draw at which its cumulative value peaks (its best height of draw), as the flow model predicts its grades.",
    fields: &[
        f("drawpoint", Str, "-", "Drawpoint name", true, &[]),
        f("best_hod", F64, "m", "Height of draw at the peak of the cumulative value (0 if it never rose above zero)", true, &[]),
        f("best_tonnes", F64, "t", "Tonnes drawn by then", true, &[]),
        f("best_value", F64, "currency", "The peak cumulative value", true, &[]),
        f("best_period", I64, "-", "Period of the peak (-1 if it never rose above zero)", true, &[]),
        f("final_hod", F64, "m", "Height of draw at the end of the run", true, &[]),
        f("final_value", F64, "currency", "Cumulative value at the end of the run", true, &[]),
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
            "marker_caps",
            Str,
            "-",
            "The caps of the marker moves over the run: moves (marker steps) and moved_tonne_metres (sum of marker mass times step length, t m); per cap (push: the ring's push beyond R_old, at most R_old/2; squeeze: inside R_old, at most a/2; lateral: at most R_old/4; transfer_rim: a split step's transfer taken from beyond the disk's rim) the steps it cut (moves, share of all steps) and what it dropped (dropped_tonne_metres: mass times the length of the move left out; dropped_share: over moved_tonne_metres); shape_modes: the lateral move's Fourier modes beyond the kept ones, estimated per disk update (disk_updates with a lateral move, dropped_tonne_metres and dropped_share of the RMS estimate, variance_share: the share of the ring dilation's variance beyond the kept modes)",
            true,
            &[],
        ),
        f(
            "percolation",
            Str,
            "m3",
            "Fines percolation over the run (zeros with mechanisms.fines off): percolated (the fines' volume summed over the IMZ disk bases it crossed), returned (the part the bulk's slowing carried back up across the same bases), owed (the part still to carry back at the end) and left (the volume of the fines that percolated out of an IMZ, passed up that IMZ as void at its next draw)",
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
        f("value", F64, "currency", "The draw's value with [economics] (null without)", false, &[]),
        f("closed_drawpoints", I64, "-", "Drawpoints closed by draw control's closure rules (null without draw control)", false, &[]),
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
