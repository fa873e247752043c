//! The numerical stress matrix (issue 8), small: every case finite,
//! non-negative and within its analytic bound.

use footlight::bench::stress::run_matrix;

#[test]
fn every_stress_case_is_finite_and_bounded() {
    let cases = run_matrix(2_000);
    assert!(cases.len() >= 18, "{} cases", cases.len());
    let failed: Vec<String> = cases.iter().filter(|c| !c.ok).map(|c| format!("{}: {}", c.name, c.detail)).collect();
    assert!(failed.is_empty(), "failed stress cases:\n{}", failed.join("\n"));
}
