//! `stairbench perceive`: the plane-segment estimation (the paper's §4, or `--method cells`)
//! on a scenario's simulated scan, a PLY / PCD cloud, or a voxel file such as the paper's
//! `voxels.txt`.

use anyhow::{bail, Result};
use clap::Args;
use serde_json::json;
use stairbench::cloud::io::{read_cloud, read_xyz_text};
use stairbench::cloud::PointCloud;
use stairbench::perception::{
    median_timed, metrics, perceive, perceive_voxels, Method, NeighbourSearch, Perception,
};
use stairbench::scene::Scene;
use stairbench::sensor::AssembleParams;
use stairbench::sim::scan_scenario;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Arguments of `stairbench perceive`.
#[derive(Debug, Args)]
pub struct PerceiveArgs {
    /// A scenario (file or name: its world is scanned first), a cloud (.ply, .pcd), or voxel
    /// representatives as x,y,z rows (.txt, e.g. the paper's voxels.txt: Filters 1-2 skipped).
    input: Option<PathBuf>,
    /// Estimate the normals on exactly k neighbours (default: the paper's k = 10 of §5,
    /// grown in proportion to the sweep's measured range noise above 10 mm). The paper's
    /// pipeline only (`--method paper`, or a cloud without a scan grid).
    #[arg(short, long)]
    k: Option<usize>,
    /// Neighbourhood search of the normal estimation (auto: the scan grid when the cloud
    /// has one). The paper's pipeline only, as `-k`.
    #[arg(long, value_enum)]
    search: Option<SearchArg>,
    /// How the planes are found: the paper's §4 pipeline, or planes grown on cells of the
    /// scan grid (a cloud without one, a file of points, runs the paper's). Default: the
    /// parameters' [perception] method, the cells.
    #[arg(long, value_enum)]
    method: Option<MethodArg>,
    /// Climb parameters as TOML (as for `run --params`): its [perception] table. The options
    /// above override it.
    #[arg(long, value_name = "FILE.toml")]
    params: Option<PathBuf>,
    #[command(flatten)]
    noise: super::NoiseArgs,
    /// Print one JSON object (segments, timings_ms, counts, and the score against ground
    /// truth for a scenario) instead of tables.
    #[arg(long)]
    json: bool,
    /// Run the pipeline this many times and report the run of median total time.
    #[arg(long, default_value_t = 1)]
    repeat: usize,
    /// Sweep the real sensor head of this hardware file (or `stairbench emulate`) and find
    /// the steps in its cloud.
    #[arg(long, value_name = "FILE.toml", conflicts_with = "input")]
    hardware: Option<PathBuf>,
}

/// `--method` values.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum MethodArg {
    Paper,
    Cells,
}

/// `--search` values.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum SearchArg {
    Auto,
    KdTree,
    ScanGrid,
}

enum Input {
    Scenario(Box<Scene>, PointCloud),
    Cloud(PointCloud),
    Voxels(PointCloud),
}

/// What the input is, by its name: a file of points (a cloud or voxel rows, with no scan
/// grid) or a sweep (the hardware's, or a scenario's scan).
#[derive(Clone, Copy, PartialEq)]
enum Kind {
    Hardware,
    CloudFile,
    VoxelFile,
    Scenario,
}

fn kind(a: &PerceiveArgs) -> Kind {
    if a.hardware.is_some() {
        return Kind::Hardware;
    }
    let ext =
        a.input.as_deref().and_then(Path::extension).and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("ply" | "pcd") => Kind::CloudFile,
        Some("txt" | "xyz" | "csv") => Kind::VoxelFile,
        _ => Kind::Scenario,
    }
}

fn load(a: &PerceiveArgs) -> Result<Input> {
    match (kind(a), a.input.as_deref(), &a.hardware) {
        (Kind::Hardware, _, Some(hw)) => {
            let (_, sweep) = super::hardware_sweep(hw, a.json, None)?;
            Ok(Input::Cloud(sweep.assemble(&AssembleParams::default())?))
        }
        (Kind::CloudFile, Some(p), _) => Ok(Input::Cloud(read_cloud(p)?)),
        (Kind::VoxelFile, Some(p), _) => Ok(Input::Voxels(read_xyz_text(p)?)),
        (_, arg, _) => {
            let mut scenario = super::load_scenario(arg)?;
            a.noise.apply(&mut scenario);
            let scan = scan_scenario(&scenario, &mut |_, _| {})?;
            let cloud = scan.sweep.assemble(&AssembleParams::default())?;
            Ok(Input::Scenario(Box::new(scan.scene), cloud))
        }
    }
}

/// Runs `stairbench perceive`.
pub fn run(a: PerceiveArgs) -> Result<ExitCode> {
    let mut params = super::climb_params(a.params.as_deref())?.perception;
    if let Some(k) = a.k {
        params.normal_neighbours = k;
        params.k_grows_with_noise = false;
    }
    if let Some(search) = a.search {
        params.neighbour_search = match search {
            SearchArg::Auto => NeighbourSearch::Auto,
            SearchArg::KdTree => NeighbourSearch::KdTree,
            SearchArg::ScanGrid => NeighbourSearch::ScanGrid,
        };
    }
    match a.method {
        Some(MethodArg::Paper) => params.method = Method::Paper,
        Some(MethodArg::Cells) => params.method = Method::Cells,
        None => {}
    }
    // A scenario's scan and the hardware's sweep are organized grids, which the cells take;
    // a points file has none and runs the paper's pipeline whatever the method.
    let sweep = matches!(kind(&a), Kind::Hardware | Kind::Scenario);
    let paper_only = a.k.is_some() || a.search.is_some_and(|s| !matches!(s, SearchArg::Auto));
    if params.method == Method::Cells && sweep && paper_only {
        bail!(
            "-k and --search set the normals of the paper's pipeline, and the cell method computes none: drop them or use --method paper"
        );
    }
    let input = load(&a)?;
    let (cloud, voxels, scene) = match &input {
        Input::Scenario(scene, cloud) => (cloud, false, Some(scene.as_ref())),
        Input::Cloud(cloud) => (cloud, false, None),
        Input::Voxels(cloud) => (cloud, true, None),
    };
    let run_once = || if voxels { perceive_voxels(cloud, &params) } else { perceive(cloud, &params) };
    let result = match median_timed(a.repeat, run_once) {
        Ok(r) => r,
        Err(e) => {
            if a.json {
                println!("{}", json!({ "segments": [], "error": e.to_string() }));
            } else {
                println!("{e}");
            }
            return Ok(ExitCode::from(1));
        }
    };
    let score = scene.map(|s| metrics::score(&result.segments, s.steps(), params.voxel_resolution_m));
    if a.json {
        println!("{}", serde_json::to_string_pretty(&to_json(&result, score.as_ref()))?);
    } else {
        print_tables(&result, score.as_ref());
    }
    Ok(ExitCode::SUCCESS)
}

fn to_json(r: &Perception, score: Option<&metrics::Score>) -> serde_json::Value {
    let segments: Vec<_> = r
        .segments
        .iter()
        .map(|s| {
            json!({
                "corners": s.corners().iter().map(|c| [c.x, c.y, c.z]).collect::<Vec<_>>(),
                "height": s.height_m(),
                "area": s.area_m2(),
                "depth": s.depth_m(),
                "width": s.width_m(),
                "normal": [s.normal().x, s.normal().y, s.normal().z],
                "voxels": s.voxel_count(),
            })
        })
        .collect();
    let mut v = json!({
        "method": r.method.to_string(),
        "segments": segments,
        "timings_ms": r.timings,
        "counts": r.counts,
    });
    if let Some(s) = score {
        v["score"] = serde_json::to_value(s).unwrap_or_default();
    }
    v
}

fn print_tables(r: &Perception, score: Option<&metrics::Score>) {
    let c = &r.counts;
    match r.method {
        Method::Paper => {
            println!(
                "{} points -> {} after Filter 1 -> {} voxels -> {} after Filter 2 -> {} supervoxels -> {} clusters, {} after Filter 3 -> {} planes -> {} segments -> {} steps",
                c.points, c.after_filter1, c.voxels, c.after_filter2, c.supervoxels, c.clusters, c.after_filter3, c.planes, c.segments, r.segments.len()
            );
            let noise =
                c.range_noise_mm.map(|mm| format!(" (range noise {mm:.1} mm, measured on the sweep)"));
            println!("normals on k = {} neighbours{}", c.normal_neighbours, noise.unwrap_or_default());
        }
        Method::Cells => {
            println!(
                "{} points -> {} cells fitted, {} level planes -> {} regions holding {} points, {} columns -> {} segments -> {} steps",
                c.points, c.cells, c.level_cells, c.planes, c.after_filter1, c.voxels, c.segments, r.segments.len()
            );
            if let Some(mm) = c.range_noise_mm {
                println!("planes grown on the scan grid (range noise {mm:.1} mm, measured on the sweep)");
            }
        }
    }
    println!("step  height   depth   width   area     voxels  centre (x, y)");
    for (i, s) in r.segments.iter().enumerate() {
        let ctr = s.center();
        println!(
            "{:>4}  {:>6.3}  {:>6.3}  {:>6.3}  {:>6.4}  {:>6}   ({:.3}, {:.3})",
            i + 1,
            s.height_m(),
            s.depth_m(),
            s.width_m(),
            s.area_m2(),
            s.voxel_count(),
            ctr.x,
            ctr.y
        );
    }
    if let Some(sc) = score {
        println!(
            "against ground truth: {} of {} steps found, {} false segments",
            sc.found,
            sc.steps.len(),
            sc.false_segments
        );
        println!(
            "true step  found  IoU    dz (mm)  corners (mm)  front (mm)  back (mm)  area p (Eq. 3)  coverage"
        );
        for s in &sc.steps {
            println!(
                "{:>9}  {:>5}  {:.2}  {:>7.1}  {:>12.1}  {:>10.1}  {:>9.1}  {:>12.1} %  {:>6.1} %",
                s.index + 1,
                if s.found { "yes" } else { "no" },
                s.iou,
                s.height_error_m * 1e3,
                s.corner_error_m * 1e3,
                s.front_error_m * 1e3,
                s.back_error_m * 1e3,
                s.area_percent,
                s.coverage_percent
            );
        }
    }
    let t = &r.timings;
    if r.method == Method::Cells {
        println!(
            "timings (ms): cells {:.2}, regions {:.2}, staircase {:.2}, total {:.2}",
            t.cells_ms, t.regions_ms, t.staircase_ms, t.total_ms
        );
        return;
    }
    println!(
        "timings (ms): normals {:.2}, filter1 {:.2}, voxels+filter2 {:.2}, supervoxels {:.2}, clusters+filter3 {:.2}, ransac {:.2}, staircase {:.2}, total {:.2}",
        t.normals_ms, t.filter1_ms, t.voxels_ms, t.supervoxels_ms, t.clusters_ms, t.ransac_ms, t.staircase_ms, t.total_ms
    );
}
