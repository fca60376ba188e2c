//! A load case's studied von Mises peaks as the summaries, the file and the page carry them:
//! the verdict, the value with its error or the note that it is singular, and the line that
//! says it. The accuracy stage (`accuracy/peak.rs`) makes them (solving the peaks again on meshes refined
//! around them); the load stage only carries them.

/// How a peak behaved as the mesh around it was refined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Its changes fall at order ≥ 0.5: extrapolated, with an error.
    Converging,
    /// Its changes fall, slowly: extrapolated, with a large error.
    Slow,
    /// It rises at each refinement without slowing: a singular point (re-entrant edge, a
    /// support's edge, a point load); no converged value exists.
    Singular,
    /// Its changes change sign or do not fall: no error is stated.
    Unsettled,
}

impl Verdict {
    /// The word the summaries use.
    pub fn word(self) -> &'static str {
        match self {
            Verdict::Converging => "converging",
            Verdict::Slow => "slow",
            Verdict::Singular => "singular",
            Verdict::Unsettled => "unsettled",
        }
    }
}

/// One peak of a load case's von Mises stress, studied.
#[derive(Clone, Debug, serde::Serialize)]
pub struct PeakStress {
    /// Where it is on the basis's mesh (a corner vertex), m.
    pub at_m: [f64; 3],
    /// Its value on the basis's mesh (the one stored and shown), Pa.
    pub value_pa: f64,
    /// The largest von Mises near it with the element size there halved, then quartered, Pa.
    pub refined_pa: [f64; 2],
    /// The basis mesh's element size there (mean edge length at the vertex), m.
    pub local_size_m: f64,
    /// How it behaved.
    pub verdict: Verdict,
    /// The observed order of convergence per halving of the size (converging and slow).
    pub order: Option<f64>,
    /// The value extrapolated to a mesh of size 0 (converging and slow), Pa.
    pub extrapolated_pa: Option<f64>,
    /// The estimated error of `value_pa` (converging and slow), Pa.
    pub error_pa: Option<f64>,
    /// What the summaries print.
    pub text: String,
}

impl PeakStress {
    /// As the basis file stores it.
    pub fn record(&self) -> ves_format::PeakRecord {
        ves_format::PeakRecord {
            verdict: self.verdict.word().to_string(),
            value: self.value_pa,
            error: self.error_pa,
            refined: self.refined_pa,
            position: self.at_m,
        }
    }
}

/// The largest of a case's studied `peaks` (largest first) that is not singular, when the
/// largest is: the stress to judge the part by.
pub fn regular(peaks: &[PeakStress]) -> Option<&PeakStress> {
    match peaks.first() {
        Some(p) if p.verdict == Verdict::Singular => peaks.iter().find(|p| p.verdict != Verdict::Singular),
        _ => None,
    }
}

/// A one-line account of a studied peak, in MPa.
pub fn describe(p: &ves_format::PeakRecord) -> String {
    let mpa = |x: f64| format!("{:.4} MPa", x / 1e6);
    let at = format!("({:.4}, {:.4}, {:.4}) m", p.position[0], p.position[1], p.position[2]);
    let values = format!(
        "{} → {} → {} with the element size there halved twice",
        mpa(p.value),
        mpa(p.refined[0]),
        mpa(p.refined[1]),
    );
    match (p.verdict.as_str(), p.error) {
        ("singular", _) => format!(
            "von Mises {} at {at} is at a singular point (a re-entrant edge, a support's or a load's edge): \
             {values}; it has no mesh-converged value",
            mpa(p.value)
        ),
        (verdict, Some(e)) => format!(
            "von Mises {} ± {:.1} % at {at} ({verdict}: {values})",
            mpa(p.value),
            100.0 * e / p.value.abs().max(f64::MIN_POSITIVE),
        ),
        _ => format!(
            "von Mises {} at {at}: unsettled ({values}); no error is stated — refine the mesh there",
            mpa(p.value)
        ),
    }
}

/// What a load case's summary says of its peak stress: the largest peak, and when that one is
/// singular the largest that is not (the stress to judge the part by).
pub fn case_text(peak: Option<&ves_format::PeakRecord>, regular: Option<&ves_format::PeakRecord>) -> Option<String> {
    let first = describe(peak?);
    Some(match regular {
        Some(r) => format!("peak {first}; away from it, {}", describe(r)),
        None if peak?.verdict == "singular" => {
            format!("peak {first}; every peak studied is singular — judge the part by the stress away from them")
        }
        None => format!("peak {first}"),
    })
}
