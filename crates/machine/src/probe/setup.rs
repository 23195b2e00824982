//! One stylus on one artefact: directions, the reference centre and the observed pretravel
//! (`docs/spec/machine-physics.md`, "Kind `probe`", "Touch k": sphere δ = R + r + (x − C)·a,
//! ring δ = (x − C)·a − (R − r), µm), the global model, the statistics and the statements.

use dbbcal_core::acceptance::decide;
use dbbcal_core::probe_campaign::{
    angle_between_deg, ArtefactDecl, ArtefactKind, ProbeTouch, StylusDecl,
};

use crate::linear::{self, LinearProblem, LinearSolution};

use super::diagnose;
use super::effects::{ProbeEffect, TouchInputs};
use super::harmonics::fit_harmonics;
use super::model::{self, Lobing, ModelFit, ModelSpec};
use super::stats::{self, direction_spread, two_touch_summary};
use super::{
    ArtefactFit, DirectionResult, EffectiveTip, FormCheck, LobingResult, ModelResult,
    NotIdentifiable, Parameter, ProbeStudyError, ProbeStudyOptions, SetupStudy, TouchResult,
};

/// A direction: its first approach, spindle, and members.
struct Group {
    approach: [f64; 3],
    spindle: Option<f64>,
    members: Vec<usize>,
}

/// Touches grouped by direction (within `tol_deg` of the group's first approach, same
/// spindle), groups ordered by spindle, φ, θ. Returns each touch's group and the groups.
fn group_directions(touches: &[ProbeTouch], tol_deg: f64) -> (Vec<usize>, Vec<Group>) {
    let mut groups: Vec<Group> = Vec::new();
    for (i, t) in touches.iter().enumerate() {
        let found = groups.iter_mut().find(|g| {
            g.spindle == t.spindle_deg && angle_between_deg(&g.approach, &t.approach) <= tol_deg
        });
        match found {
            Some(g) => g.members.push(i),
            None => groups.push(Group {
                approach: t.approach,
                spindle: t.spindle_deg,
                members: vec![i],
            }),
        }
    }
    let key = |g: &Group| {
        let t = &touches[g.members[0]];
        (
            g.spindle.unwrap_or(0.0),
            (t.phi_deg() * 1e6).round() as i64,
            (t.theta_deg() * 1e6).round() as i64,
        )
    };
    groups.sort_by(|a, b| {
        let (ka, kb) = (key(a), key(b));
        ka.0.total_cmp(&kb.0)
            .then(ka.1.cmp(&kb.1))
            .then(ka.2.cmp(&kb.2))
    });
    let mut of = vec![0; touches.len()];
    for (g, group) in groups.iter().enumerate() {
        for &m in &group.members {
            of[m] = g;
        }
    }
    (of, groups)
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The observed pretravel of a touch relative to centre `c_mm`, µm.
fn pretravel_um(
    kind: ArtefactKind,
    big_r_mm: f64,
    r_mm: f64,
    t: &ProbeTouch,
    c_mm: &[f64; 3],
) -> f64 {
    let d = [
        t.position_mm[0] - c_mm[0],
        t.position_mm[1] - c_mm[1],
        t.position_mm[2] - c_mm[2],
    ];
    match kind {
        ArtefactKind::Sphere => 1e3 * (big_r_mm + r_mm + dot(&d, &t.approach)),
        ArtefactKind::Ring => 1e3 * (dot(&d, &t.approach) - (big_r_mm - r_mm)),
    }
}

/// A first centre from the touches: each touch's point moved back along the approach by the
/// nominal radius of the tip-centre surface, averaged.
fn first_centre(kind: ArtefactKind, big_r_mm: f64, r_mm: f64, touches: &[ProbeTouch]) -> [f64; 3] {
    let mut c = [0.0; 3];
    let reach = match kind {
        ArtefactKind::Sphere => -(big_r_mm + r_mm),
        ArtefactKind::Ring => big_r_mm - r_mm,
    };
    for t in touches {
        for (k, ck) in c.iter_mut().enumerate() {
            *ck += t.position_mm[k] - reach * t.approach[k];
        }
    }
    c.map(|v| v / touches.len() as f64)
}

/// Whether two spindle orientations among the touches lie 180° (± 1°) apart.
fn spindle_pairs(touches: &[ProbeTouch]) -> bool {
    let mut s: Vec<f64> = touches.iter().filter_map(|t| t.spindle_deg).collect();
    s.sort_by(f64::total_cmp);
    s.dedup();
    s.iter().any(|a| {
        s.iter()
            .any(|b| ((b - a).rem_euclid(360.0) - 180.0).abs() <= 1.0)
    })
}

fn u_k2(s: &LinearSolution, name: &str) -> f64 {
    match s.index(name) {
        Some(i) if s.determined[i] => 2.0 * s.std_uncertainty(name).unwrap_or(f64::NAN),
        _ => f64::NAN,
    }
}

fn value(s: &LinearSolution, name: &str) -> f64 {
    match s.index(name) {
        Some(i) if s.determined[i] => s.estimate[i],
        _ => f64::NAN,
    }
}

/// c·x and its U (k = 2) from the solution's covariance.
fn combination(s: &LinearSolution, c: &[f64]) -> (f64, f64) {
    let v: f64 = c.iter().zip(&s.estimate).map(|(a, b)| a * b).sum();
    let var = s.covariance.as_ref().map_or(f64::NAN, |cov| {
        let mut acc = 0.0;
        for i in 0..c.len() {
            for j in 0..c.len() {
                acc += c[i] * c[j] * cov[(i, j)];
            }
        }
        acc
    });
    (v, 2.0 * var.max(0.0).sqrt())
}

/// Analyse one stylus on one artefact.
pub(crate) fn study_setup(
    stylus: &StylusDecl,
    artefact: &ArtefactDecl,
    touches: &[ProbeTouch],
    tol_deg: f64,
    options: &ProbeStudyOptions,
) -> Result<SetupStudy, ProbeStudyError> {
    let (of, groups) = group_directions(touches, tol_deg);
    let kind = artefact.kind;
    let big_r = artefact.diameter_mm / 2.0;
    let r = stylus.tip_diameter_mm / 2.0;
    if groups.len() < 3 {
        return Err(ProbeStudyError::Setup {
            stylus: stylus.id.clone(),
            artefact: artefact.id.clone(),
            problem: format!(
                "{} direction(s): at least 3 are needed for a centre and a radius",
                groups.len()
            ),
        });
    }
    let t0 = touches.iter().map(|t| t.time_ns).min().unwrap_or(0);
    let inputs: Vec<TouchInputs> = touches
        .iter()
        .zip(&of)
        .map(|(t, &d)| TouchInputs {
            a: t.approach,
            phi_deg: t.phi_deg(),
            spindle_deg: t.spindle_deg.unwrap_or(0.0),
            first: t.is_first(),
            direction: d,
            hours: (t.time_ns - t0) as f64 / 3.6e12,
            feed_mm_min: t.feed_mm_min,
        })
        .collect();
    let spec = ModelSpec {
        centre_dims: match kind {
            ArtefactKind::Ring => 2,
            ArtefactKind::Sphere => 3,
        },
        tip_offset: spindle_pairs(touches),
        lobing: options.lobing,
        effects: options.effects.clone(),
        directions: groups.len(),
    };
    let declared = artefact.centre_mm.is_some();
    let mut centre = artefact
        .centre_mm
        .unwrap_or_else(|| first_centre(kind, big_r, r, touches));
    let y_of = |c: &[f64; 3]| -> Vec<f64> {
        touches
            .iter()
            .map(|t| pretravel_um(kind, big_r, r, t, c))
            .collect()
    };
    let mut y = y_of(&centre);
    let mut fit = model::fit(&spec, &inputs, &y)?;
    if !declared {
        // Move the reference centre to the fitted one (twice: the model is linear in ΔC).
        for _ in 0..2 {
            for k in 0..spec.centre_dims {
                let d = value(&fit.solution, &format!("centre_{}_um", ["x", "y", "z"][k]));
                if d.is_finite() {
                    centre[k] += 1e-3 * d;
                }
            }
            y = y_of(&centre);
            fit = model::fit(&spec, &inputs, &y)?;
        }
    }
    let diagnosis = diagnose::run(&spec, &inputs, &y, &fit, options)?;
    // Direction statistics on the pretravel relative to the analysis' centre.
    let centre_part = |i: usize| -> f64 {
        if declared {
            return 0.0;
        }
        (0..spec.centre_dims)
            .map(|k| {
                let v = value(&fit.solution, &format!("centre_{}_um", ["x", "y", "z"][k]));
                if v.is_finite() {
                    v * inputs[i].a[k]
                } else {
                    0.0
                }
            })
            .sum()
    };
    let pre: Vec<f64> = (0..touches.len()).map(|i| y[i] - centre_part(i)).collect();
    let visits = visits_by_direction(touches, &of, groups.len(), &pre);
    let spreads: Vec<_> = visits.iter().map(|v| direction_spread(v)).collect();
    let summary = two_touch_summary(&spreads);
    let directions = direction_results(&groups, touches, &spreads, &spec, &fit, &inputs, &of);
    let harmonics = {
        let phi: Vec<f64> = directions.iter().map(|d| d.phi_deg).collect();
        let v: Vec<f64> = spreads.iter().map(two_touch_mean).collect();
        let pooled = summary.two_sigma_2on_um / 2.0;
        let u: Vec<f64> = spreads
            .iter()
            .map(|s| {
                let n = (s.touches - s.visits).max(1) as f64;
                let sd = if s.two_sigma_2on_um.is_finite() {
                    s.two_sigma_2on_um / 2.0
                } else {
                    pooled
                };
                if sd.is_finite() {
                    sd / n.sqrt()
                } else {
                    1e-3
                }
            })
            .collect();
        fit_harmonics(&phi, &v, &u)?
    };
    let lobing = lobing_result(&fit);
    let artefact_fit = artefact_fit(artefact, &spec, &fit, &inputs, &of, centre, r);
    let delta = artefact_fit.mean_pretravel_um;
    let tip = EffectiveTip {
        nominal_mm: stylus.tip_diameter_mm,
        effective_mm: stylus.tip_diameter_mm - 2e-3 * delta.0,
        u_k2_um: 2.0 * ((delta.1).powi(2) + artefact.u_um.powi(2)).sqrt(),
    };
    let form = form_check(artefact, &spec, &inputs, &y, &summary, options.mpe_um)?;
    let not_identifiable = statements(
        declared,
        &spec,
        &fit,
        &harmonics,
        groups.len(),
        &artefact_fit,
    );
    let model = model_result(&fit, touches.len());
    let touch_results = touches
        .iter()
        .enumerate()
        .map(|(i, t)| TouchResult {
            seq: t.seq,
            direction: of[i] + 1,
            touch_in_direction: t.touch_in_direction,
            pretravel_um: pre[i],
            residual_um: fit.solution.residuals[i],
        })
        .collect();
    Ok(SetupStudy {
        stylus: stylus.id.clone(),
        artefact: artefact.id.clone(),
        directions,
        summary,
        harmonics,
        lobing,
        artefact_fit,
        tip,
        form,
        model,
        diagnosis,
        not_identifiable,
        touches: touch_results,
    })
}

/// Each direction's visits (a new visit at every touch 1), values in touch order.
fn visits_by_direction(
    touches: &[ProbeTouch],
    of: &[usize],
    n: usize,
    values: &[f64],
) -> Vec<Vec<Vec<f64>>> {
    let mut visits: Vec<Vec<Vec<f64>>> = vec![Vec::new(); n];
    let mut last: Option<usize> = None;
    for (i, t) in touches.iter().enumerate() {
        let d = of[i];
        if t.is_first() || last != Some(d) || visits[d].is_empty() {
            visits[d].push(Vec::new());
        }
        if let Some(v) = visits[d].last_mut() {
            v.push(values[i]);
        }
        last = Some(d);
    }
    visits
}

/// The two-touch mean, or the all-touch mean where no visit has a second touch.
fn two_touch_mean(s: &stats::DirectionSpread) -> f64 {
    if s.mean_2on_um.is_finite() {
        s.mean_2on_um
    } else {
        s.mean_all_um
    }
}

/// The row of `spec` at a direction restricted to the pretravel and lobing columns.
fn pretravel_row(spec: &ModelSpec, fit: &ModelFit, t: &TouchInputs) -> Vec<f64> {
    let phi0 = fit
        .phi0_deg
        .map_or(0.0, |p| if p.0.is_finite() { p.0 } else { 0.0 });
    let full = model::row(spec, t, phi0);
    let names = model::names(spec);
    full.into_iter()
        .zip(&names)
        .map(|(v, n)| {
            if n == "pretravel_mean_um" || n.starts_with("lobe") {
                v
            } else {
                0.0
            }
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn direction_results(
    groups: &[Group],
    touches: &[ProbeTouch],
    spreads: &[stats::DirectionSpread],
    spec: &ModelSpec,
    fit: &ModelFit,
    inputs: &[TouchInputs],
    of: &[usize],
) -> Vec<DirectionResult> {
    let means: Vec<f64> = spreads.iter().map(two_touch_mean).collect();
    let grand = stats::mean(&means);
    let first_touch = fit.spec.effects.contains(&ProbeEffect::FirstTouch);
    groups
        .iter()
        .enumerate()
        .map(|(d, g)| {
            let t = &touches[g.members[0]];
            let input = &inputs[of.iter().position(|&x| x == d).unwrap_or(0)];
            let row = pretravel_row(spec, fit, input);
            let model_pretravel_um: f64 = row
                .iter()
                .zip(&fit.solution.estimate)
                .map(|(a, b)| a * b)
                .sum();
            let s = &spreads[d];
            let n2 = (s.touches - s.visits).max(1) as f64;
            let sd = s.two_sigma_2on_um / 2.0;
            let name = format!("first_touch_d{:02}_um", d + 1);
            DirectionResult {
                index: d + 1,
                approach: t.approach,
                phi_deg: t.phi_deg(),
                theta_deg: t.theta_deg(),
                spindle_deg: g.spindle,
                spread: s.clone(),
                model_pretravel_um,
                correction_um: -(means[d] - grand),
                correction_u_k2_um: 2.0 * sd / n2.sqrt(),
                first_touch_fit_um: first_touch
                    .then(|| (value(&fit.solution, &name), u_k2(&fit.solution, &name))),
            }
        })
        .collect()
}

fn lobing_result(fit: &ModelFit) -> LobingResult {
    let s = &fit.solution;
    match fit.spec.lobing {
        Lobing::Physical => {
            // δ_min at a seat phase the touches do not fix means nothing: not determined.
            let phase = fit.phi0_deg.unwrap_or((f64::NAN, f64::NAN));
            let fixed = phase.1.is_finite();
            let d = if fixed {
                value(s, "lobe_delta_min_um")
            } else {
                f64::NAN
            };
            let u = if fixed {
                u_k2(s, "lobe_delta_min_um")
            } else {
                f64::NAN
            };
            LobingResult {
                model: Lobing::Physical,
                size_um: (d, u),
                phase_deg: phase,
                peak_to_valley_um: d,
            }
        }
        Lobing::Harmonic => {
            let (c, sn) = (value(s, "lobe3_cos_um"), value(s, "lobe3_sin_um"));
            let a = c.hypot(sn);
            let (uc, us) = (u_k2(s, "lobe3_cos_um"), u_k2(s, "lobe3_sin_um"));
            let u = if a > 0.0 {
                ((c * uc).powi(2) + (sn * us).powi(2)).sqrt() / a
            } else {
                uc.max(us)
            };
            let phase = (sn.atan2(c).to_degrees() / 3.0).rem_euclid(120.0);
            let u_phase = if a > 0.0 {
                (u / a).to_degrees() / 3.0
            } else {
                f64::NAN
            };
            LobingResult {
                model: Lobing::Harmonic,
                size_um: (a, u),
                phase_deg: (phase, u_phase),
                peak_to_valley_um: 2.0 * a,
            }
        }
    }
}

fn artefact_fit(
    artefact: &ArtefactDecl,
    spec: &ModelSpec,
    fit: &ModelFit,
    inputs: &[TouchInputs],
    of: &[usize],
    centre: [f64; 3],
    r_mm: f64,
) -> ArtefactFit {
    let s = &fit.solution;
    let centre_offset_um = (0..spec.centre_dims)
        .map(|k| {
            let name = format!("centre_{}_um", ["x", "y", "z"][k]);
            (name.clone(), value(s, &name), u_k2(s, &name))
        })
        .collect();
    // δ̄: the model's pretravel averaged over the directions.
    let directions = spec.directions;
    let mut c = vec![0.0; s.estimate.len()];
    for d in 0..directions {
        if let Some(i) = of.iter().position(|&x| x == d) {
            for (acc, v) in c.iter_mut().zip(pretravel_row(spec, fit, &inputs[i])) {
                *acc += v / directions as f64;
            }
        }
    }
    let delta = combination(s, &c);
    let big_r = artefact.diameter_mm / 2.0;
    let apparent = match artefact.kind {
        ArtefactKind::Sphere => big_r + r_mm - 1e-3 * delta.0,
        ArtefactKind::Ring => big_r - r_mm + 1e-3 * delta.0,
    };
    ArtefactFit {
        kind: artefact.kind,
        centre_declared: artefact.centre_mm.is_some(),
        centre_mm: centre,
        centre_offset_um,
        apparent_radius_mm: apparent,
        apparent_radius_u_k2_um: delta.1,
        mean_pretravel_um: delta,
    }
}

/// ISO 10360-5-style P: the range of the radial residuals of the least-squares centre and
/// radius over every touch; U from the artefact's certified form (rectangular) and the
/// two-touch σ; decided against the MPE by ISO 14253-1.
fn form_check(
    artefact: &ArtefactDecl,
    spec: &ModelSpec,
    inputs: &[TouchInputs],
    y: &[f64],
    summary: &stats::TwoTouchSummary,
    mpe_um: Option<f64>,
) -> Result<FormCheck, ProbeStudyError> {
    let mut names = vec!["radius_um".to_string()];
    for k in 0..spec.centre_dims {
        names.push(format!("centre_{}_um", ["x", "y", "z"][k]));
    }
    let rows = inputs
        .iter()
        .map(|t| {
            let mut r = vec![1.0];
            r.extend(t.a.iter().take(spec.centre_dims));
            r
        })
        .collect();
    let s = linear::solve(&LinearProblem {
        names,
        rows,
        observations: y.to_vec(),
        sigma: None,
    })?;
    let p = stats::range(&s.residuals);
    let sigma = summary.two_sigma_2on_um / 2.0;
    let form = artefact.form_um.unwrap_or(0.0);
    let u = 2.0
        * (form * form / 3.0
            + if sigma.is_finite() {
                sigma * sigma
            } else {
                0.0
            })
        .sqrt();
    Ok(FormCheck {
        p_form_um: p,
        u_k2_um: u,
        mpe_um,
        decision: mpe_um.map(|m| decide(p, u, m)),
        note: format!(
            "{} touches in {} directions on a {} (ISO 10360-5 asks 25 points over a test sphere's hemisphere: this is the same evaluation on these touches)",
            inputs.len(),
            spec.directions,
            artefact.kind.as_str()
        ),
    })
}

fn statements(
    declared: bool,
    spec: &ModelSpec,
    fit: &ModelFit,
    harmonics: &super::HarmonicFit,
    directions: usize,
    a: &ArtefactFit,
) -> Vec<NotIdentifiable> {
    let mut out = vec![NotIdentifiable {
        name: "0th harmonic ≡ tip radius",
        says: format!(
            "the mean pretravel ({:.3} µm) and the tip radius act alike: only the certified diameter separates them, so the effective tip diameter carries both",
            a.mean_pretravel_um.0
        ),
    }];
    if !spec.tip_offset {
        let h1 = harmonics.order(1);
        let says = if declared {
            format!(
                "with the centre declared, the direction means hold a 1st harmonic of {:.2} µm (phase {:.0}°): a centre offset (or a constant tip offset, stylus run-out), not pretravel; repeat the touches at spindle orientations 180° apart to tell them apart",
                h1.map_or(f64::NAN, |h| h.amplitude_um),
                h1.map_or(f64::NAN, |h| h.phase_deg)
            )
        } else {
            "the fitted centre absorbs any 1st harmonic of the pretravel, a constant tip offset and stylus run-out, for any number of directions; declare the centre or repeat the touches at spindle orientations 180° apart to tell them apart".to_string()
        };
        out.push(NotIdentifiable {
            name: "1st harmonic ≡ centre offset",
            says,
        });
    }
    let sin3_lost = harmonics.lost.iter().any(|l| l.contains("h3_sin_um"))
        || fit.phi0_deg.is_some_and(|p| !p.1.is_finite());
    if sin3_lost {
        out.push(NotIdentifiable {
            name: "6 directions: sin 3φ unseen",
            says: format!(
                "{directions} directions: sin 3φ is zero at every one of them, so the lobes' phase is not fixed and the tri-lobe cannot be told from any other three-fold content (a three-lobed artefact); at least 12 directions are needed, 24 are better"
            ),
        });
    }
    out.push(NotIdentifiable {
        name: "stylus bending ≡ lobing",
        says:
            "stylus bending ∝ the trigger force has the same three lobes: it is inside the lobing"
                .into(),
    });
    out
}

fn model_result(fit: &ModelFit, touches: usize) -> ModelResult {
    let s = &fit.solution;
    ModelResult {
        lobing: fit.spec.lobing,
        effects: fit.spec.effects.clone(),
        parameters: s
            .names
            .iter()
            .map(|n| Parameter {
                name: n.clone(),
                value: value(s, n),
                u_k2: u_k2(s, n),
            })
            .collect(),
        rank: s.rank,
        lost: s.lost.iter().map(|l| l.to_string()).collect(),
        rms_um: fit.rms_um,
        touches,
    }
}
