//! `stairbench polygon`: the static-stability polygon of a stance given as JSON, for
//! engineers checking a stance by hand.

use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use serde::Deserialize;
use stairbench::geom2d;
use stairbench::planning::dd::DdParams;
use stairbench::planning::polygon::{by_bretl, by_double_description};
use stairbench::planning::{Contact, ContactSpec};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// Arguments of `stairbench polygon`.
#[derive(Debug, Args)]
pub struct PolygonArgs {
    /// The stance: `{"contacts": [{"center": [x, y, z], "rpy": [roll, pitch, yaw],
    /// "half_length": 0.12, "half_width": 0.065, "friction": 0.7}, ...]}` (metres, radians;
    /// a contact's normal is its local z; rpy defaults to 0, friction to 0.7). `-` reads stdin.
    stance: PathBuf,
    /// The method: double description of the contact wrench cone (dd), or Bretl and Lall's
    /// projection with LPs (bretl), an independent check.
    #[arg(long, value_enum, default_value = "dd")]
    method: Method,
    /// Bretl's tolerance, metres (each edge within it of the true boundary).
    #[arg(long, default_value_t = 1e-5)]
    tolerance_m: f64,
    /// Print `{"vertices": [[x, y], ...]}` (counter-clockwise) instead of a table.
    #[arg(long)]
    json: bool,
}

/// `--method` values.
#[derive(Debug, Clone, Copy, ValueEnum)]
enum Method {
    Dd,
    Bretl,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Stance {
    contacts: Vec<ContactSpec>,
}

/// Runs `stairbench polygon`.
pub fn run(a: PolygonArgs) -> Result<ExitCode> {
    let text = if a.stance.as_os_str() == "-" {
        std::io::read_to_string(std::io::stdin()).context("cannot read the stance from stdin")?
    } else {
        std::fs::read_to_string(&a.stance).with_context(|| format!("cannot read {}", a.stance.display()))?
    };
    let stance: Stance =
        serde_json::from_str(&text).with_context(|| format!("{}: not a stance", a.stance.display()))?;
    let contacts: Vec<Contact> = stance
        .contacts
        .iter()
        .enumerate()
        .map(|(i, c)| c.build(i))
        .collect::<Result<_, _>>()
        .with_context(|| format!("{}", a.stance.display()))?;
    let t0 = Instant::now();
    let result = match a.method {
        Method::Dd => by_double_description(&contacts, &DdParams::default()),
        Method::Bretl => by_bretl(&contacts, a.tolerance_m),
    };
    let elapsed_ms = t0.elapsed().as_secs_f64() * 1e3;
    let poly = match result {
        Ok(p) => p,
        Err(e) => {
            if a.json {
                println!("{}", serde_json::json!({ "vertices": [], "error": e.to_string() }));
            } else {
                println!("{e}");
            }
            return Ok(ExitCode::from(1));
        }
    };
    if a.json {
        let v: Vec<[f64; 2]> = poly.iter().map(|p| [p.x, p.y]).collect();
        println!(
            "{}",
            serde_json::json!({ "vertices": v, "area_m2": geom2d::area(&poly), "time_ms": elapsed_ms })
        );
    } else {
        println!(
            "static-stability polygon of {} contacts ({:?}, {elapsed_ms:.3} ms), counter-clockwise:",
            contacts.len(),
            a.method
        );
        println!("       x (m)       y (m)");
        for p in &poly {
            println!("  {:>10.4}  {:>10.4}", p.x, p.y);
        }
        println!("area {:.4} m^2", geom2d::area(&poly));
    }
    Ok(ExitCode::SUCCESS)
}
