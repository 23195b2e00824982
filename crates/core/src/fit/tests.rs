use super::autocorrelation::{initial_autocorrelation, initial_positive_sums, DIRECT_ACF_MAX_LAG};
use super::hac::satterthwaite_dof;
use super::*;

/// `y = b1 (1 - exp(-b2 x))` with `b2` nonlinear (NIST Misra1a / BoxBOD form).
struct Exponential {
    x: Vec<f64>,
    y: Vec<f64>,
}
impl Separable for Exponential {
    fn observations(&self) -> &[f64] {
        &self.y
    }
    fn nonlinear_names(&self) -> Vec<String> {
        vec!["b2".into()]
    }
    fn linear_names(&self) -> Vec<String> {
        vec!["b1".into()]
    }
    fn basis(&self, t: &[f64]) -> DMatrix<f64> {
        DMatrix::from_iterator(
            self.x.len(),
            1,
            self.x.iter().map(|x| 1.0 - (-t[0] * x).exp()),
        )
    }
    fn basis_derivative(&self, t: &[f64], _k: usize) -> DMatrix<f64> {
        DMatrix::from_iterator(
            self.x.len(),
            1,
            self.x.iter().map(|x| x * (-t[0] * x).exp()),
        )
    }
}

/// With white noise the gain's HAC variance has few degrees of freedom and comes out low
/// half the time; the reported `u` (never below the white-noise one, [`Fit::se`]) keeps the
/// errors beyond 3 u near the normal 0.27 %, where the HAC u alone lets several times more
/// through, and the 95 % intervals cover at least nominally.
#[test]
fn the_reported_u_is_never_below_the_white_noise_one() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let n = 2000;
    let switches = [500.0, 1200.0, 1700.0];
    let decay = |i: usize| {
        let t = i as f64;
        switches
            .iter()
            .rev()
            .find(|&&s| t >= s)
            .map_or(0.0, |s| (-(t - s) / 30.0).exp())
    };
    let columns = DMatrix::from_fn(n, 2, |i, j| if j == 0 { 1.0 } else { decay(i) });
    let normal = Normal::new(0.0, 1.0).unwrap();
    let reps = 4000;
    let (mut beyond, mut beyond_hac, mut covered, mut floored) = (0, 0, 0, 0);
    for seed in 0..reps {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let y = (0..n)
            .map(|i| 2.0 * decay(i) + normal.sample(&mut rng))
            .collect();
        // A level and a gain on decays after three switches (`tau` 30 samples): the gain's
        // information sits in a few batches.
        let p = FixedColumns {
            y,
            phi: columns.clone(),
            names: vec!["level".into(), "gain".into()],
        };
        let f = fit(&p, &[], &FitOptions::default()).unwrap();
        let err = f.values[1] - 2.0;
        let u = f.se(1);
        assert!(u >= f.se_naive(1));
        beyond += usize::from(err.abs() > 3.0 * u);
        beyond_hac += usize::from(err.abs() > 3.0 * f.cov_hac[(1, 1)].sqrt());
        covered += usize::from(err.abs() <= f.t95(1) * u);
        floored += usize::from(f.cov_hac[(1, 1)] < f.cov_naive[(1, 1)]);
    }
    let share = |k: usize| k as f64 / reps as f64;
    eprintln!(
        "beyond 3 u: {:.2} % (HAC u alone {:.2} %); 95 % intervals cover {:.1} %; white-noise u taken {:.0} %",
        100.0 * share(beyond),
        100.0 * share(beyond_hac),
        100.0 * share(covered),
        100.0 * share(floored)
    );
    assert!(share(beyond) < 0.006, "{beyond} of {reps} beyond 3 u");
    assert!(beyond_hac >= 3 * beyond.max(1), "HAC alone: {beyond_hac}");
    assert!((0.94..=0.985).contains(&share(covered)));
}

/// The Gauss-Newton polish ([`Start::NearOptimum`]) reaches Levenberg-Marquardt's optimum
/// in a few steps from near it, and from far (where it may not converge, Levenberg-Marquardt
/// takes over) still reaches it.
#[test]
fn the_polish_from_a_near_start_reaches_the_optimum_and_falls_back_from_a_far_one() {
    let x: Vec<f64> = (0..200).map(|i| i as f64 * 0.5).collect();
    let y = x
        .iter()
        .enumerate()
        .map(|(i, x)| {
            3.0 * (1.0 - (-0.07 * x).exp()) + 0.01 * ((i * 7919 % 97) as f64 / 48.0 - 1.0)
        })
        .collect();
    let p = Exponential { x, y };
    let with = |start: Start, theta0: f64| {
        let options = FitOptions {
            start,
            hac_batch_len: Some(1),
            absorbed_params: 0,
            stop: Stop::Numerical,
        };
        fit(&p, &[theta0], &options).unwrap()
    };
    let reference = with(Start::Given, 0.07);
    for theta0 in [0.0735, 0.07 * 0.95, 2.0, 0.001] {
        let polished = with(Start::NearOptimum, theta0);
        for (a, b) in polished.values.iter().zip(&reference.values) {
            assert!((a - b).abs() <= 1e-7 * b.abs(), "from {theta0}: {a} vs {b}");
        }
        assert!((polished.rss - reference.rss).abs() <= 1e-12 * reference.rss);
        if (theta0 / 0.07 - 1.0).abs() < 0.1 {
            assert!(polished.iterations <= 4, "{} steps", polished.iterations);
        }
    }
}

#[test]
fn recovers_noise_free_exponential() {
    let x: Vec<f64> = (0..50).map(|i| i as f64).collect();
    let y = x.iter().map(|x| 3.0 * (1.0 - (-0.07 * x).exp())).collect();
    let p = Exponential { x, y };
    let f = fit(
        &p,
        &[0.2],
        &FitOptions {
            start: Start::Given,
            hac_batch_len: None,
            absorbed_params: 0,
            stop: Stop::Numerical,
        },
    )
    .unwrap();
    assert!((f.values[0] - 3.0).abs() < 1e-9, "{:?}", f.values);
    assert!((f.values[1] - 0.07).abs() < 1e-11, "{:?}", f.values);
}

/// A term fitted beyond fixed directions recovers its own parameters exactly when the rest of
/// the signal lies in their span, even with a rank-deficient set of directions.
#[test]
fn orthogonalised_fit_sees_only_what_the_directions_cannot_explain() {
    let x: Vec<f64> = (0..200).map(|i| i as f64).collect();
    let d1: Vec<f64> = x.iter().map(|x| (x / 5.0).sin()).collect();
    let d2: Vec<f64> = x.iter().map(|x| x / 50.0).collect();
    let y = x
        .iter()
        .zip(d1.iter().zip(&d2))
        .map(|(x, (a, b))| 3.0 * (1.0 - (-0.07 * x).exp()) + 2.0 * a + 0.5 * b)
        .collect();
    let p = Exponential { x, y };
    let mut directions = DMatrix::zeros(200, 3);
    for r in 0..200 {
        directions[(r, 0)] = d1[r];
        directions[(r, 1)] = 2.0 * d1[r];
        directions[(r, 2)] = d2[r];
    }
    let o = Orthogonalised::new(&p, &directions);
    let along: f64 = o.observations().iter().zip(&d2).map(|(y, d)| y * d).sum();
    assert!(along.abs() < 1e-9, "observations keep {along} along d2");
    let options = FitOptions {
        start: Start::Given,
        hac_batch_len: None,
        absorbed_params: 0,
        stop: Stop::Numerical,
    };
    let f = fit(&o, &[0.2], &options).unwrap();
    assert!((f.values[0] - 3.0).abs() < 1e-8, "{:?}", f.values);
    assert!((f.values[1] - 0.07).abs() < 1e-10, "{:?}", f.values);
    assert!(f.rss < 1e-16, "rss {}", f.rss);
    // Without the directions the same term cannot fit the signal.
    assert!(fit(&p, &[0.2], &options).unwrap().rss > 1.0);
}

#[test]
fn satterthwaite_dof_is_batches_minus_one_for_equal_batches_and_less_when_one_dominates() {
    // One parameter (a mean): every batch carries the same information, ν = B − 1.
    let jac = DMatrix::from_element(200, 1, 1.0);
    let nu = satterthwaite_dof(&jac, &k_inv_of(&jac), 10, None).unwrap();
    assert!((nu[0] - 19.0).abs() < 1e-9, "{nu:?}");
    // A slope whose information sits at the ends: fewer effective batches.
    let jac = DMatrix::from_fn(200, 2, |i, j| {
        if j == 0 {
            1.0
        } else {
            (i as f64 / 199.0 - 0.5).powi(3)
        }
    });
    let nu = satterthwaite_dof(&jac, &k_inv_of(&jac), 10, None).unwrap();
    assert!(nu[1] < 10.0 && nu[1] >= 1.0, "{nu:?}");
    // The same with the mean absorbed as a group: the slope's ν is unchanged (the column is
    // orthogonal to the mean), the projected-out mean still costs its degree of freedom.
    let mut centred = jac.column(1).into_owned();
    let m = centred.mean();
    centred.add_scalar_mut(-m);
    let groups: Vec<Option<usize>> = vec![Some(0); 200];
    let centred = DMatrix::from_columns(&[centred]);
    let nu_g = satterthwaite_dof(&centred, &k_inv_of(&centred), 10, Some(&groups)).unwrap();
    assert!((nu_g[0] - nu[1]).abs() < 1e-9 * nu[1], "{nu_g:?} {nu:?}");
}

/// [`satterthwaite_dof`] against its definition, built densely on a small problem: `M = (I − H)
/// A (I − H)`, `A = blockdiag(a_b a_bᵀ)`, `H` the projection on the Jacobian and the group
/// indicators, `ν = (tr M)² / tr(M²)`. Uneven batches (the last one short), groups that span
/// batches, and samples in no group.
#[test]
fn satterthwaite_dof_matches_its_definition_built_densely() {
    let (n, p, batch) = (61, 3, 7);
    let mut state = 11u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let groups: Vec<Option<usize>> = (0..n).map(|i| (i % 13 != 0).then_some(i / 17)).collect();
    let mut jac = DMatrix::from_fn(n, p, |i, j| uniform() + (i as f64 / 9.0).sin() * j as f64);
    // The problem demeans the Jacobian within each group (`absorbed_groups`).
    let n_groups = 1 + groups.iter().flatten().max().unwrap();
    for j in 0..p {
        for g in 0..n_groups {
            let members: Vec<usize> = (0..n).filter(|&i| groups[i] == Some(g)).collect();
            let mean = members.iter().map(|&i| jac[(i, j)]).sum::<f64>() / members.len() as f64;
            for &i in &members {
                jac[(i, j)] -= mean;
            }
        }
    }
    let k_inv = k_inv_of(&jac);
    let mut z = DMatrix::<f64>::zeros(n, n_groups);
    for (i, g) in groups.iter().enumerate() {
        if let Some(g) = g {
            z[(i, *g)] = 1.0;
        }
    }
    let ztz_inv = (z.transpose() * &z).try_inverse().unwrap();
    let h = &jac * &k_inv * jac.transpose() + &z * ztz_inv * z.transpose();
    let i_h = DMatrix::<f64>::identity(n, n) - h;
    let a_all = &jac * &k_inv;
    let fast = satterthwaite_dof(&jac, &k_inv, batch, Some(&groups)).unwrap();
    for (k, nu) in fast.iter().enumerate() {
        let mut a = DMatrix::<f64>::zeros(n, n);
        for b in (0..n).step_by(batch) {
            let end = (b + batch).min(n);
            for i in b..end {
                for j in b..end {
                    a[(i, j)] = a_all[(i, k)] * a_all[(j, k)];
                }
            }
        }
        let m = &i_h * a * &i_h;
        let dense = (m.trace() * m.trace() / (&m * &m).trace()).max(1.0);
        assert!(
            (nu - dense).abs() < 1e-9 * dense,
            "k {k}: {nu} against {dense}"
        );
    }
}

#[test]
fn profile_interval_matches_wald_when_nearly_linear_and_follows_the_rss() {
    // Exponential with small noise: the profile of b2 is close to quadratic, so the interval
    // cut at delta = t² var / [(JᵀJ)⁻¹]_kk is close to b2 ± t u, and the RSS at its ends
    // has risen by exactly delta.
    let mut state = 7u64;
    let x: Vec<f64> = (0..200).map(|i| i as f64 * 0.25).collect();
    let y: Vec<f64> = x
        .iter()
        .map(|x| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let e = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            3.0 * (1.0 - (-0.07 * x).exp()) + 0.01 * e
        })
        .collect();
    let p = Exponential { x, y };
    let f = fit(&p, &[0.2], &FitOptions::default()).unwrap();
    let theta = [f.values[1]];
    let (u, t) = (f.se_naive(1), 2.0);
    let s2 = f.rss / (f.n_obs - 2) as f64;
    let delta = t * t * u * u / (f.cov_naive[(1, 1)] / s2);
    let interval = profile_interval(&p, &theta, 0, f.rss, delta, t * u).unwrap();
    assert_eq!(interval.at_search_bound, [false; 2]);
    let [lo, hi] = interval.ends;
    assert!(
        (theta[0] - lo - t * u).abs() < 0.03 * t * u,
        "{lo} {theta:?} {u}"
    );
    assert!(
        (hi - theta[0] - t * u).abs() < 0.03 * t * u,
        "{hi} {theta:?} {u}"
    );
    for end in [lo, hi] {
        let rise = projected_rss(&p, &[end]) - f.rss;
        assert!((rise - delta).abs() < 0.02 * delta, "{rise} {delta}");
    }
}

/// `n` samples of an AR(1) process `v = phi v + e` driven by uniform noise on ±0.5 from a
/// linear congruential generator seeded with `seed` (phi = 0: white noise).
fn uniform_ar1(seed: u64, phi: f64, n: usize) -> Vec<f64> {
    let mut state = seed;
    let mut v = 0.0;
    (0..n)
        .map(|_| {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let e = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            v = phi * v + e;
            v
        })
        .collect()
}

#[test]
fn acf_of_white_noise_is_small() {
    let x = uniform_ar1(12345, 0.0, 4000);
    let acf = autocorrelation(&x, 10);
    assert!((acf[0] - 1.0).abs() < 1e-12);
    assert!(acf[1..].iter().all(|r| r.abs() < 0.06), "{acf:?}");
    assert!(integrated_autocorrelation_time(&x) < 1.2);
}

#[test]
fn acf_of_ar1_matches_phi() {
    let x = uniform_ar1(99, 0.9, 20000);
    let acf = autocorrelation(&x, 3);
    assert!((acf[1] - 0.9).abs() < 0.02, "{acf:?}");
    // tau_int of AR(1) = (1+phi)/(1-phi) = 19
    let tau = integrated_autocorrelation_time(&x);
    assert!((tau - 19.0).abs() < 4.0, "{tau}");
}

/// The direct initial autocorrelation equals the FFT one (to rounding) up to its first
/// non-positive lag, where it stops; a series still correlated at the direct limit gets the
/// FFT's whole autocorrelation.
#[test]
fn initial_autocorrelation_is_the_fft_one_up_to_its_first_non_positive_lag() {
    for (seed, phi) in [(7, 0.0), (8, 0.5), (9, 0.9), (10, 0.995)] {
        let x = uniform_ar1(seed, phi, 20000);
        let fft = autocorrelation(&x, x.len() / 2);
        let direct = initial_autocorrelation(&x);
        for (k, (d, f)) in direct.iter().zip(&fft).enumerate() {
            assert!((d - f).abs() < 1e-12, "phi {phi} lag {k}: {d} vs {f}");
        }
        let first_non_positive = fft.iter().position(|r| *r <= 0.0).unwrap();
        if first_non_positive <= DIRECT_ACF_MAX_LAG {
            assert_eq!(direct.len(), first_non_positive + 1, "phi {phi}");
        } else {
            assert_eq!(direct.len(), fft.len(), "phi {phi}");
        }
        let (sums_d, sums_f) = (initial_positive_sums(&direct), initial_positive_sums(&fft));
        assert!((sums_d.0 - sums_f.0).abs() < 1e-12 * sums_f.0, "phi {phi}");
        assert!(
            (sums_d.1 - sums_f.1).abs() <= 1e-12 * sums_f.1.abs(),
            "phi {phi}"
        );
    }
}

/// White residuals keep the short batch (n^(1/3)); a slow AR(1) part 30 times below the
/// white noise (autocorrelations of 1e-3 a lag, invisible to the sample ACF) lengthens it
/// past its correlation time, where batch means hold its variance.
#[test]
fn variance_time_batches_find_a_slow_part_under_white_noise() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let n = 400_000;
    let normal = Normal::new(0.0, 1.0).unwrap();
    let mut lengthened_white = 0;
    for seed in 0..40 {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let white: Vec<f64> = (0..n).map(|_| normal.sample(&mut rng)).collect();
        if hac_batch_length(&white) != 74 {
            lengthened_white += 1;
        }
        if seed >= 4 {
            continue;
        }
        // AR(1) with correlation time 1000 samples and sd 1/30 of the white noise.
        let phi = (-1.0f64 / 1000.0).exp();
        let innovation = (1.0 - phi * phi).sqrt() / 30.0;
        let mut w = 0.0;
        let slow: Vec<f64> = white
            .iter()
            .map(|v| {
                w = phi * w + innovation * normal.sample(&mut rng);
                v + w
            })
            .collect();
        assert!(
            integrated_autocorrelation_time(&slow) < 2.0,
            "seed {seed}: the ACF sees the slow part"
        );
        let batch = hac_batch_length(&slow);
        assert!(batch >= 2000, "seed {seed}: batch {batch}");
    }
    assert!(
        lengthened_white <= 1,
        "{lengthened_white} of 40 white series got a longer batch"
    );
}

/// A saturated exponential (`x` ≥ 10 / b2) says b2 is large but not how large: the profile
/// interval's upper end is the search bound, and says so; the lower end is a real limit.
#[test]
fn profile_interval_flags_an_end_the_data_do_not_bound() {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let noise = Normal::new(0.0, 0.01).unwrap();
    let x: Vec<f64> = (0..200).map(|i| 10.0 + i as f64 * 0.5).collect();
    let y = x
        .iter()
        .map(|x| 3.0 * (1.0 - (-1.0 * x).exp()) + noise.sample(&mut rng))
        .collect();
    let p = Exponential { x, y };
    let theta = [1.0];
    let rss = projected_rss(&p, &theta);
    let s2 = rss / 198.0;
    let interval = profile_interval(&p, &theta, 0, rss, 4.0 * s2, 0.1).unwrap();
    assert_eq!(interval.at_search_bound, [false, true], "{interval:?}");
    assert_eq!(interval.ends[1], 1.0 + 6.4);
    assert!(
        interval.ends[0] > 0.1 && interval.ends[0] < 1.0,
        "{interval:?}"
    );
}

/// `(JᵀJ)⁻¹`, as [`fit`] passes it to the covariances.
fn k_inv_of(jac: &DMatrix<f64>) -> DMatrix<f64> {
    super::gram(jac).try_inverse().unwrap()
}

/// One decay `exp(-x / tau)` (`θ = ln tau`) fitted to the sum of a fast, large decay and a slow,
/// small one: the projected RSS over `θ` has a minimum near each, the fast one the lower.
struct OneDecay {
    x: Vec<f64>,
    y: Vec<f64>,
}
impl OneDecay {
    fn new() -> OneDecay {
        let x: Vec<f64> = (0..4000).map(f64::from).collect();
        let y = x
            .iter()
            .map(|x| 16.0 * (-x / 8.0).exp() + (-x / 2000.0).exp())
            .collect();
        OneDecay { x, y }
    }
}
impl Separable for OneDecay {
    fn observations(&self) -> &[f64] {
        &self.y
    }
    fn nonlinear_names(&self) -> Vec<String> {
        vec!["ln_tau".into()]
    }
    fn linear_names(&self) -> Vec<String> {
        vec!["gain".into()]
    }
    fn basis(&self, t: &[f64]) -> DMatrix<f64> {
        let tau = t[0].exp();
        DMatrix::from_iterator(self.x.len(), 1, self.x.iter().map(|x| (-x / tau).exp()))
    }
    fn basis_derivative(&self, t: &[f64], _k: usize) -> DMatrix<f64> {
        let tau = t[0].exp();
        DMatrix::from_iterator(
            self.x.len(),
            1,
            self.x.iter().map(|x| (-x / tau).exp() * x / tau),
        )
    }
    fn start_search_interval(&self, _k: usize) -> Option<(f64, f64)> {
        Some((0.0, 12.0))
    }
}

/// From a start in the slow decay's basin, Brent over the whole interval settles there (its
/// first point, the interval's golden section, lies in that basin); the global search (grid,
/// then Brent in the best point's bracket) finds the lower minimum: no point of a fine grid is
/// lower than its result.
#[test]
fn the_global_start_search_finds_the_lowest_of_two_minima() {
    let p = OneDecay::new();
    let rss = |theta: f64| projection::projected_rss(&p, &[theta]);
    let (brent, _) = minimise(&p, &[7.0], StartSearch::Brent, Stop::Statistical).unwrap();
    let (global, _) = minimise(&p, &[7.0], StartSearch::Global, Stop::Statistical).unwrap();
    let finest = (0..=1200)
        .map(|i| rss(i as f64 * 0.01))
        .fold(f64::INFINITY, f64::min);
    eprintln!(
        "Brent: tau {:.1}, RSS {:.6}; global: tau {:.1}, RSS {:.6}; finest grid {:.6}",
        brent[0].exp(),
        rss(brent[0]),
        global[0].exp(),
        rss(global[0]),
        finest
    );
    assert!(rss(global[0]) <= finest * (1.0 + 1e-9));
    assert!(
        rss(brent[0]) > 1.01 * rss(global[0]),
        "the case no longer traps Brent: it tests nothing"
    );
}
