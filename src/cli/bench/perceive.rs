//! `bench perceive`: the perception pipeline's speed and quality. Reproduces the paper's Fig. 5
//! (first-step area and time against k, on Exp. 1 and Exp. 2), breaks the time down per phase
//! at k = 10, compares with the k-d tree baseline in the same process, and runs the PCL peer
//! (../shared/peers) on the same exported cloud when its binary is there.

use super::{machine, plot};
use anyhow::{bail, Context, Result};
use stairbench::cloud::io::{write_cloud, CloudFormat};
use stairbench::cloud::PointCloud;
use stairbench::geom2d;
use stairbench::perception::normals::grid_window;
use stairbench::perception::{
    median_timed, metrics, perceive, Method, NeighbourSearch, Perception, PerceptionParams, PerceptionStream,
    PhaseTimings,
};
use stairbench::scene::Scene;
use stairbench::sensor::AssembleParams;
use stairbench::sim::scan_scenario;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The k values of Fig. 5.
const K_RANGE: std::ops::RangeInclusive<usize> = 5..=25;
/// The paper's chosen k (§5).
const K_PAPER: usize = 10;
/// Where the PCL peer's binary is when built by ../shared/peers/run_all.sh.
const PCL_DEFAULT: &str = "/tmp/peers/build/pcl_pipeline";

/// One scanned cloud and the world it came from.
struct Case {
    label: String,
    scene: Scene,
    cloud: PointCloud,
}

/// The median run (by total time) of `repeat` runs, after one warm-up.
fn median_run(cloud: &PointCloud, p: &PerceptionParams, repeat: usize) -> Result<Perception> {
    let _ = perceive(cloud, p);
    Ok(median_timed(repeat, || perceive(cloud, p))?)
}

/// What [`streamed_run`] measured.
struct Streamed {
    /// The steps of the last run.
    found: Perception,
    /// The median time from the last row's arrival to the steps, ms.
    after_ms: f64,
    /// The median over the runs of that time over the whole sweep's perception run just
    /// before it: the machine's state cancels out.
    of_whole: f64,
    /// The median time of those whole-sweep runs, ms.
    whole_ms: f64,
    /// The most time one earlier row's arrival took, ms.
    row_ms: f64,
}

/// `cloud`'s sweep given to a [`PerceptionStream`] row by row, as the lidar sends it, `repeat`
/// times after a warm-up, each run after the whole sweep's perception ([`perceive`]).
fn streamed_run(cloud: &PointCloud, p: &PerceptionParams, repeat: usize) -> Result<Streamed> {
    let rows = cloud.grid().map_or(0, |g| g.rows());
    let mut after_ms = Vec::with_capacity(repeat);
    let mut of_whole = Vec::with_capacity(repeat);
    let mut whole = Vec::with_capacity(repeat);
    let mut row_ms: f64 = 0.0;
    let mut last = None;
    for run in 0..=repeat {
        let t = Instant::now();
        perceive(cloud, p)?;
        let whole_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut stream = PerceptionStream::new(cloud, p)?;
        for r in 1..rows {
            let t = Instant::now();
            stream.arrived(cloud, r);
            row_ms = row_ms.max(t.elapsed().as_secs_f64() * 1e3);
        }
        let t = Instant::now();
        stream.arrived(cloud, rows);
        let found = stream.finish(cloud)?;
        if run > 0 {
            let ms = t.elapsed().as_secs_f64() * 1e3;
            after_ms.push(ms);
            of_whole.push(ms / whole_ms);
            whole.push(whole_ms);
        }
        last = Some(found);
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let found = last.context("no run")?;
    Ok(Streamed {
        found,
        after_ms: median(after_ms),
        of_whole: median(of_whole),
        whole_ms: median(whole),
        row_ms,
    })
}

fn scan(name: &str, noise_mm: f64) -> Result<Case> {
    let mut scenario = crate::cli::load_scenario(Some(Path::new(name)))?;
    scenario.lidar.noise_sigma_m = noise_mm / 1000.0;
    let scan = scan_scenario(&scenario, &mut |_, _| {})?;
    let cloud = scan.sweep.assemble(&AssembleParams::default())?;
    let label = format!(
        "{}, {}",
        match scenario.name.as_str() {
            "exp1" => "Exp. 1".to_string(),
            "exp2" => "Exp. 2".to_string(),
            other => other.to_string(),
        },
        if noise_mm > 0.0 { format!("sigma {noise_mm:.0} mm") } else { "noise-free".into() }
    );
    Ok(Case { label, scene: scan.scene, cloud })
}

/// One point of the Fig. 5 sweep.
pub struct SweepPoint {
    /// Neighbours of the normal estimation.
    pub k: usize,
    /// Eq. 3 area of the first step, percent (NaN when not found).
    pub first_area_percent: f64,
    /// Footprint coverage of the first step, percent.
    pub first_coverage_percent: f64,
    /// Total time, ms.
    pub total_ms: f64,
    /// Steps found / true steps in view.
    pub found: usize,
}

/// Runs the whole benchmark; returns the Markdown section.
/// `plot`: where to draw Fig. 5, and the link to it that the Markdown table ends with.
pub fn run(repeat: usize, fig5_at: Option<(&Path, &str)>, pcl: Option<&Path>) -> Result<String> {
    eprintln!("scanning Exp. 1 and Exp. 2, with and without noise ...");
    let cases = vec![scan("exp1", 10.0)?, scan("exp1", 0.0)?, scan("exp2", 10.0)?, scan("exp2", 0.0)?];
    let mut out = String::new();
    out += &format!(
        "Perception (§4) on simulated tilting-lidar scans at the default lidar settings (240 rows x 1081 beams), median of {repeat} runs after a warm-up; {}.\n\n",
        machine()
    );

    // Speed at k = 10: baseline, variants and PCL, on Exp. 1 with noise.
    eprintln!("speed at k = {K_PAPER} ...");
    let exp1 = &cases[0];
    let paper = PerceptionParams { method: Method::Paper, ..Default::default() };
    let kd = PerceptionParams { neighbour_search: NeighbourSearch::KdTree, ..paper.clone() };
    let base = median_run(&exp1.cloud, &kd, repeat)?;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().context("thread pool")?;
    let single = one.install(|| median_run(&exp1.cloud, &paper, repeat))?;
    let ours = median_run(&exp1.cloud, &paper, repeat)?;
    let cells = PerceptionParams { method: Method::Cells, ..paper.clone() };
    let cells_single = one.install(|| median_run(&exp1.cloud, &cells, repeat))?;
    let cells_all = median_run(&exp1.cloud, &cells, repeat)?;
    let (hr, hb) = grid_window(K_PAPER);
    out += &format!(
        "### Speed, {} ({} points), k = {K_PAPER}\n\nTimes in ms. The baseline is the same pipeline with exact kNN normals from a k-d tree (kiddo, rebuilt per frame), as §4.1 describes; `--method paper` finds each point's k nearest among a {} x {} (rows x beams) window of the scan grid. The default (`--method cells`) grows the planes on {} x {} cells of the scan grid (perception::cells) and draws the same rectangles from them; its sweep's noise measure counts under cells. The staircase phase includes the fronts placed on the risers.\n\n",
        exp1.label,
        exp1.cloud.len(),
        2 * hr + 1,
        2 * hb + 1,
        cells.cells.rows,
        cells.cells.beams
    );
    out += &format!("| variant | {PHASES} | total | ratio to baseline | steps found | IoU steps 1/2/3 |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (name, r) in [
        ("baseline: k-d tree normals, all cores", &base),
        ("scan-grid normals, 1 thread", &single),
        ("scan-grid normals, all cores (`--method paper`)", &ours),
        ("cells of the scan grid, 1 thread", &cells_single),
        ("cells of the scan grid, all cores (default)", &cells_all),
    ] {
        out += &phase_row(name, r, &exp1.scene, base.timings.total_ms, &paper);
    }
    match pcl_peer(exp1, pcl, repeat, base.timings.total_ms, ours.timings.total_ms)? {
        Some(row) => out += &row,
        None => out += &format!(
            "| PCL peer | - | - | - | - | - | - | - | - | - | not run: no binary at {PCL_DEFAULT} (build it with ../shared/peers/run_all.sh, or pass --pcl) | | | |\n"
        ),
    }
    eprintln!("streamed ...");
    let Streamed { found: streamed, after_ms, of_whole, whole_ms, row_ms } =
        streamed_run(&exp1.cloud, &cells, repeat)?;
    let goal = 5.0 / whole_ms;
    let same = if streamed.segments == cells_all.segments {
        "the same steps as the whole sweep's"
    } else {
        "steps that DIFFER from the whole sweep's"
    };
    out += &format!(
        "\nStreamed (the default method, `PerceptionStream`): the sweep's rows given one by one as the lidar sends them (one every 25 ms), each row's range differences (counted into the noise median's histogram) and each completed row of cells' sums taken as they arrive; the rest (the median's selection within its bin, the cells judged, regions, points, columns, staircase, risers) after the last. Steps ready **{after_ms:.1} ms** after the last row (median of {repeat}), **{of_whole:.2}** of the whole sweep's perception time (each streamed run after a whole-sweep run in the same process, {whole_ms:.1} ms the median of those; the median of their ratios, in which the machine's state cancels out: the 5 ms goal asks {goal:.2} of this run's whole sweep), {same}; the most one row's arrival took: {row_ms:.2} ms.\n"
    );

    // Fig. 5 (b): phases at k = 10 on every cloud.
    eprintln!("phases per cloud ...");
    out += &format!("\n### Fig. 5 (b): time per phase at k = {K_PAPER}, ms (Exp. 2's upper steps are beyond the sweep's view from the start on the floor, the found count out of all 11: the paper, too, reconstructs them after climbing the lower ones, §5, the closed loop's job)\n\n");
    out += &format!("| cloud | points | {PHASES} | total | supervoxels (count) | steps found | IoU per step |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for c in &cases {
        let r = median_run(&c.cloud, &paper, repeat)?;
        let s = metrics::score(&r.segments, c.scene.steps(), paper.voxel_resolution_m);
        out += &format!(
            "| {} | {} | {} | {} | {}/{} | {} |\n",
            c.label,
            c.cloud.len(),
            phase_cells(&r.timings),
            r.counts.supervoxels,
            s.found,
            s.steps.len(),
            ious(&s)
        );
    }

    // Fig. 5 (a): first-step area and total time against k.
    eprintln!("Fig. 5 sweep over k = {}..{} ...", K_RANGE.start(), K_RANGE.end());
    let mut series: Vec<(String, Vec<SweepPoint>)> = Vec::new();
    for c in &cases {
        let mut pts = Vec::new();
        for k in K_RANGE {
            let p = PerceptionParams { normal_neighbours: k, ..paper.clone() };
            let r = median_run(&c.cloud, &p, repeat)?;
            let s = metrics::score(&r.segments, c.scene.steps(), p.voxel_resolution_m);
            let first = s.steps.first();
            pts.push(SweepPoint {
                k,
                first_area_percent: first.filter(|f| f.found).map_or(f64::NAN, |f| f.area_percent),
                first_coverage_percent: first.filter(|f| f.found).map_or(f64::NAN, |f| f.coverage_percent),
                total_ms: r.timings.total_ms,
                found: s.found,
            });
        }
        series.push((c.label.clone(), pts));
    }
    out += "\n### Fig. 5 (a): first step against k\n\nPer cloud: Eq. 3 area p of the first step (voxel count x 4 cm² / true area; a tread lying on a voxel-layer boundary counts twice, so p can pass 100 %), its footprint coverage (the true top's area covered by the found rectangle, at most 100 %), steps found of those in the scenario, and the total time in ms; k = 5, 15, 25 (the plot has them all).\n\n";
    out += "| k |";
    for (label, _) in &series {
        out += &format!(" {label}: p / coverage / found / ms |");
    }
    out += "\n|---|";
    out += &"---|".repeat(series.len());
    out += "\n";
    for (i, k) in K_RANGE.enumerate().step_by(10) {
        out += &format!("| {k} |");
        for (si, (_, pts)) in series.iter().enumerate() {
            let p = &pts[i];
            let pct = |v: f64| if v.is_finite() { format!("{v:.0} %") } else { "not found".into() };
            out += &format!(
                " {} / {} / {}/{} / {:.1} |",
                pct(p.first_area_percent),
                pct(p.first_coverage_percent),
                p.found,
                cases[si].scene.steps().len(),
                p.total_ms
            );
        }
        out += "\n";
    }
    if let Some((path, link)) = fig5_at {
        plot::fig5(path, &series)?;
        out += &format!("\n![Fig. 5 reproduced: {link}]({link})\n");
    }
    Ok(out)
}

fn file_name(p: &Path) -> String {
    p.file_name().map(|f| f.to_string_lossy().into_owned()).unwrap_or_default()
}

fn ious(s: &metrics::Score) -> String {
    s.steps.iter().map(|st| format!("{:.2}", st.iou)).collect::<Vec<_>>().join(" / ")
}

/// The phases' column heads, as [`phase_cells`] fills them.
const PHASES: &str =
    "normals | filter 1 | voxels + filter 2 | supervoxels | clusters + filter 3 | RANSAC | cells | regions | staircase";

/// The phase times of one run as table cells ([`PHASES`]; "-" for a phase its method does
/// not run), then the total in bold.
fn phase_cells(t: &PhaseTimings) -> String {
    let phases = [
        t.normals_ms,
        t.filter1_ms,
        t.voxels_ms,
        t.supervoxels_ms,
        t.clusters_ms,
        t.ransac_ms,
        t.cells_ms,
        t.regions_ms,
        t.staircase_ms,
    ];
    let cells: Vec<String> =
        phases.iter().map(|v| if *v > 0.0 { format!("{v:.1}") } else { "-".into() }).collect();
    format!("{} | **{:.1}**", cells.join(" | "), t.total_ms)
}

fn phase_row(name: &str, r: &Perception, scene: &Scene, base_ms: f64, p: &PerceptionParams) -> String {
    let s = metrics::score(&r.segments, scene.steps(), p.voxel_resolution_m);
    format!(
        "| {name} | {} | {:.2} | {}/{} | {} |\n",
        phase_cells(&r.timings),
        base_ms / r.timings.total_ms,
        s.found,
        s.steps.len(),
        ious(&s)
    )
}

/// Runs the PCL peer on `case`'s cloud exported as PCD; its table row (ratios against the
/// baseline `base_ms` and the paper's pipeline here, `ours_ms`), or `None` when the binary is absent.
fn pcl_peer(
    case: &Case,
    pcl: Option<&Path>,
    repeat: usize,
    base_ms: f64,
    ours_ms: f64,
) -> Result<Option<String>> {
    let bin = match pcl {
        Some(p) if p.exists() => p.to_path_buf(),
        Some(p) => bail!("no PCL peer binary at {}", p.display()),
        None if Path::new(PCL_DEFAULT).exists() => PathBuf::from(PCL_DEFAULT),
        None => return Ok(None),
    };
    eprintln!("PCL peer on the same cloud ...");
    let dir = std::env::temp_dir().join(format!("stairbench-pcl-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let pcd = dir.join("exp1.pcd");
    let json = dir.join("pcl.json");
    write_cloud(&case.cloud, &pcd, CloudFormat::Pcd)?;
    let vp = case.cloud.viewpoint();
    let status = Command::new(&bin)
        .arg(&pcd)
        .args(["--runs", &repeat.to_string(), "--k", &K_PAPER.to_string()])
        .args(["--threads", &rayon::current_num_threads().to_string()])
        .arg("--vp")
        .args([vp.x, vp.y, vp.z].map(|v| v.to_string()))
        .arg("--json")
        .arg(&json)
        .stdout(std::process::Stdio::null())
        .status()
        .with_context(|| format!("cannot run {}", bin.display()))?;
    if !status.success() {
        bail!("the PCL peer {} failed ({status})", bin.display());
    }
    let text = std::fs::read_to_string(&json).with_context(|| format!("no output {}", json.display()))?;
    let _ = std::fs::remove_dir_all(&dir);
    let v: serde_json::Value = serde_json::from_str(&text).context("PCL peer's JSON")?;
    let t = &v["timings_ms"];
    let total = t["total"].as_f64().context("PCL peer's JSON has no timings_ms.total")?;
    // Score its rectangles against the same ground truth as ours.
    let rects: Vec<(Vec<geom2d::P2>, f64)> = v["segments"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|s| {
                    let c = s["corners"].as_array()?;
                    let xy: Option<Vec<geom2d::P2>> =
                        c.iter().map(|p| Some(geom2d::P2::new(p[0].as_f64()?, p[1].as_f64()?))).collect();
                    Some((xy?, s["height"].as_f64()?))
                })
                .collect()
        })
        .unwrap_or_default();
    let mut found = 0;
    let mut iou_text = Vec::new();
    for st in case.scene.steps() {
        let txy = metrics::xy(&st.corners);
        let best = rects
            .iter()
            .map(|(r, h)| (geom2d::iou(r, &txy), h - st.height_m))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or((0.0, f64::NAN));
        if best.0 >= metrics::FOUND_IOU && best.1.abs() <= metrics::FOUND_DZ_M {
            found += 1;
        }
        iou_text.push(format!("{:.2}", best.0));
    }
    let f = |key: &str| t[key].as_f64().map_or("-".to_string(), |x| format!("{x:.1}"));
    Ok(Some(format!(
        "| PCL peer ({}, same cloud as PCD, {} threads) | {} | {} | {} | {} | {} | {} | - | - | - | **{total:.1}** | {:.2} (the same pipeline here {:.0} x faster) | {found}/{} | {} |\n",
        file_name(&bin),
        rayon::current_num_threads(),
        f("normals"),
        f("filter1"),
        f("filter2"),
        f("supervoxels"),
        f("merge+filter3"),
        f("ransac+rects"),
        base_ms / total,
        total / ours_ms,
        case.scene.steps().len(),
        iou_text.join(" / ")
    )))
}
