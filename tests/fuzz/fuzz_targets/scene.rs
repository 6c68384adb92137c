//! A whole scene through `load_scene`: the input is split at NUL bytes into a block model,
//! drawpoints and a schedule (a part left out takes a small valid default), so the
//! cross-table rules (block grid, joins, ranges, units) see arbitrary tables too.
#![no_main]

use caveflow::model::load::load_scene;
use caveflow::model::Scenario;
use libfuzzer_sys::fuzz_target;

const BLOCKS: &[u8] =
    b"x,y,z,block_id,solids_density,porosity,max_porosity,friction_angle,frag_size,cu
5,5,5,1,2.7,0.3,0.45,38,0.2,1.0
15,5,5,2,2.7,0.3,0.45,38,0.2,1.1
";
const DRAWPOINTS: &[u8] = b"name,x,y,z,width\nDP1,5,5,0,4\n";
const SCHEDULE: &[u8] = b"DPName,Jan-09,31\nDP1,100,50\n";

fuzz_target!(|data: &[u8]| {
    let mut parts = data.splitn(3, |&b| b == 0);
    let blocks = parts.next().unwrap_or(BLOCKS);
    let drawpoints = parts.next().unwrap_or(DRAWPOINTS);
    let schedule = parts.next().unwrap_or(SCHEDULE);
    let dir = tempfile::tempdir().expect("temp dir");
    let write = |name: &str, bytes: &[u8]| {
        let p = dir.path().join(name);
        std::fs::write(&p, bytes).expect("write");
        p
    };
    let mut sc = Scenario::default();
    sc.inputs.blocks = write("blocks.csv", blocks);
    sc.inputs.drawpoints = write("drawpoints.csv", drawpoints);
    sc.inputs.schedule = write("schedule.csv", schedule);
    if let Ok(l) = load_scene(&sc) {
        let s = &l.scene;
        // An accepted scene is physical: the rules that guard the engine held.
        assert!(s.blocks.density.iter().all(|d| d.is_finite() && *d > 0.0));
        assert!(s.blocks.frag.iter().all(|d| d.is_finite() && *d > 0.0));
        assert!(s.drawpoints.width.iter().all(|w| w.is_finite() && *w > 0.0));
        assert!(s.schedule.tonnes.iter().all(|t| t.is_finite() && *t >= 0.0));
    }
});
