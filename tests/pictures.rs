//! The pictures draw on a machine without fonts: the capability map of three results with
//! fontconfig given no font directory at all (as in a bare CI container).

use stairbench::regress::{maps, results};
use std::path::Path;

#[test]
fn a_capability_map_draws_with_no_fonts_installed() {
    let dir = std::env::temp_dir().join(format!("stairbench-pictures-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // A fontconfig configuration that names no font directory: system fonts are not found.
    let conf = dir.join("fonts.conf");
    std::fs::write(&conf, "<?xml version=\"1.0\"?>\n<fontconfig></fontconfig>\n").unwrap();
    std::env::set_var("FONTCONFIG_FILE", &conf);
    std::env::set_var("XDG_DATA_HOME", &dir);
    let rs = results::read(Path::new("tests/fixtures/results-3.jsonl")).expect("the fixture reads");
    assert_eq!(rs.len(), 3);
    let png = dir.join("map.png");
    maps::draw(
        &png,
        "three cases: verdict over rise x tread",
        &rs,
        "rise_m",
        "tread_m",
        &[('x', 0.28, "max rise".into())],
    )
    .expect("drawn without system fonts");
    let bytes = std::fs::read(&png).unwrap();
    assert!(bytes.starts_with(b"\x89PNG") && bytes.len() > 10_000, "{} bytes", bytes.len());
    std::fs::remove_dir_all(&dir).ok();
}
