//! The JUnit XML report (quick-junit): one test case per case and noise draw; a failure's
//! type is its verdict class, its message the stop reason or first violated check, its
//! system-out the case's scenario and the command that reproduces it.

use super::results::CaseResult;
use quick_junit::{NonSuccessKind, Report, TestCase, TestCaseStatus, TestSuite};
use std::path::Path;
use std::time::Duration;

/// The report of `results` for suite `suite`; `scenario_of(id)` gives a case's scenario text.
pub fn report(suite: &str, results: &[CaseResult], scenario_of: &dyn Fn(&str) -> Option<String>) -> Report {
    let mut ts = TestSuite::new(suite);
    for r in results {
        let status = if r.pass {
            TestCaseStatus::success()
        } else {
            let mut s = TestCaseStatus::non_success(NonSuccessKind::Failure);
            s.set_type(r.verdict.name());
            s.set_message(r.message.clone().unwrap_or_else(|| r.verdict.to_string()));
            s
        };
        let name = match &r.name {
            Some(n) => format!("{} draw {} ({n})", r.id, r.seed_index),
            None => format!("{} draw {}", r.id, r.seed_index),
        };
        let mut tc = TestCase::new(name, status);
        tc.set_classname(suite);
        tc.set_time(Duration::from_secs_f64(r.wall_s.max(0.0)));
        let scenario = scenario_of(&r.id).unwrap_or_default();
        tc.set_system_out(format!(
            "verdict: {} (expected {:?}: {})\nreproduce: {}\n\n{scenario}",
            r.verdict, r.expect, r.expect_reason, r.reproduce
        ));
        ts.add_test_case(tc);
    }
    let mut report = Report::new(format!("stairbench regress {suite}"));
    report.add_test_suite(ts);
    report
}

/// Writes the report of `results` to `path`.
pub fn write(
    path: &Path,
    suite: &str,
    results: &[CaseResult],
    scenario_of: &dyn Fn(&str) -> Option<String>,
) -> Result<(), String> {
    let text = report(suite, results, scenario_of).to_string().map_err(|e| e.to_string())?;
    std::fs::write(path, text).map_err(|e| format!("{}: {e}", path.display()))
}
