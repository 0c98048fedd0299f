use super::*;
use approx::assert_abs_diff_eq;
use proptest::prelude::*;
use proto::scenario::World;

fn world(max: [f64; 2], walls: &str) -> World {
    toml::from_str(&format!(
        "min = [0.0, 0.0, 0.0]\nmax = [{}, {}, 2.5]\nwalls = [{walls}]",
        max[0], max[1]
    ))
    .unwrap()
}

fn grid(max: [f64; 2], walls: &str, cell: f64) -> Arc<Grid> {
    Arc::new(Grid::new(&world(max, walls), cell).unwrap())
}

fn mass_where(b: &Belief, f: impl Fn(f64, f64) -> bool) -> f64 {
    b.mass()
        .iter()
        .enumerate()
        .filter(|(k, _)| {
            let [x, y] = b.grid().centre_of(*k);
            f(x, y)
        })
        .map(|(_, m)| m)
        .sum()
}

/// Keep the belief only where `f` holds.
fn keep(b: &mut Belief, f: impl Fn(f64, f64) -> bool) {
    for k in 0..b.mass.len() {
        let [x, y] = b.grid.centre_of(k);
        if !f(x, y) {
            b.mass[k] = 0.0;
        }
    }
    assert!(b.normalise());
}

const WALK: RandomWalk = RandomWalk {
    sigma_per_sqrt_s: 1.0,
};

proptest! {
    /// Prediction conserves mass exactly (to rounding) and leaves blocked cells empty, for any
    /// belief, step and wall layout.
    #[test]
    fn prediction_conserves_mass_and_keeps_walls_empty(
        values in proptest::collection::vec(0.0f64..1.0, 1200),
        dt in 0.0f64..4.0,
        wall_x in 0.3f64..3.7,
        gap in 0.0f64..1.5,
    ) {
        let walls = format!(
            "{{ from = [{wall_x}, 0.0], to = [{wall_x}, {}], height = 2.0 }}, {{ from = [0.5, 2.0], to = [3.0, 2.6], height = 2.0 }}",
            3.0 - gap
        );
        let g = grid([4.0, 3.0], &walls, 0.1);
        let mut b = Belief::uniform(g.clone());
        for (k, v) in values.iter().enumerate().take(g.len()) {
            b.mass[k] = if g.is_free(k) { *v + 1e-3 } else { 0.0 };
        }
        prop_assert!(b.normalise());
        b.predict(&WALK, dt).unwrap();
        let total: f64 = b.mass().iter().sum();
        prop_assert!((total - 1.0).abs() < 1e-12, "mass {total}");
        for k in 0..g.len() {
            prop_assert!(g.is_free(k) || b.mass()[k] == 0.0);
            prop_assert!(b.mass()[k] >= 0.0 && b.mass()[k].is_finite());
        }
    }
}

/// A closed wall (outline to outline): belief on the left is not on the right after one step
/// whose kernel spans the room, even with the wall on a grid line (no blocked cells).
#[test]
fn no_leak_through_a_closed_wall() {
    for wall in [
        "{ from = [2.0, 0.0], to = [2.0, 3.0], height = 2.5 }",
        "{ from = [2.03, -0.1], to = [2.03, 3.1], height = 0.5 }",
        "{ from = [1.0, 0.0], to = [3.0, 3.0], height = 2.5 }",
    ] {
        let g = grid([4.0, 3.0], wall, 0.1);
        let side = |x: f64, y: f64| {
            // Left of the line through the wall, in its own orientation.
            let w: World = world([4.0, 3.0], wall);
            let (a, b) = (w.walls[0].from, w.walls[0].to);
            (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) > 0.0
        };
        let mut b = Belief::gaussian(g.clone(), [1.0, 1.5], 0.3);
        keep(&mut b, side);
        let start_right = mass_where(&b, |x, y| !side(x, y));
        assert_eq!(start_right, 0.0, "{wall}: the start is all on one side");
        for _ in 0..3 {
            b.predict(&WALK, 4.0).unwrap(); // σ = 2 m, kernel ±6 m
        }
        let right = mass_where(&b, |x, y| !side(x, y));
        assert_eq!(right, 0.0, "{wall}: {right} leaked");
        let total: f64 = b.mass().iter().sum();
        assert_abs_diff_eq!(total, 1.0, epsilon = 1e-12);
    }
}

/// With a gap at the wall's end, belief walks around it in one step from near the end, and
/// not at all from far below it (the only way round is the gap).
#[test]
fn belief_flows_around_the_end_of_a_wall() {
    let g = grid(
        [4.0, 3.0],
        "{ from = [2.0, 0.0], to = [2.0, 2.0], height = 2.5 }",
        0.1,
    );
    let mut near = Belief::gaussian(g.clone(), [1.7, 1.9], 0.2);
    keep(&mut near, |x, _| x < 2.0);
    near.predict(&WALK, 0.09).unwrap(); // σ = 0.3 m
    let right = mass_where(&near, |x, _| x > 2.0);
    assert!(right > 1e-3, "no flow around the wall's end ({right})");
    let mut far = Belief::gaussian(g, [1.7, 0.6], 0.2);
    keep(&mut far, |x, y| x < 2.0 && y < 1.2);
    far.predict(&WALK, 0.09).unwrap();
    assert_eq!(
        mass_where(&far, |x, _| x > 2.0),
        0.0,
        "mass crossed the wall low down"
    );
}

/// Reflecting walls neither attract nor repel: a uniform belief stays uniform.
#[test]
fn uniform_belief_is_stationary() {
    let g = grid(
        [4.0, 3.0],
        "{ from = [2.03, 0.0], to = [2.03, 2.0], height = 2.5 }, { from = [0.0, 2.2], to = [1.3, 2.9], height = 2.5 }",
        0.1,
    );
    let mut b = Belief::uniform(g.clone());
    b.predict(&WALK, 0.5).unwrap();
    let u = 1.0 / g.free_count() as f64;
    for (k, m) in b.mass().iter().enumerate() {
        let want = if g.is_free(k) { u } else { 0.0 };
        assert_abs_diff_eq!(*m, want, epsilon = 1e-15);
    }
}

/// In open space the prediction adds the random walk's variance q² dt on each axis (the
/// truncated kernel is widened to keep it).
#[test]
fn prediction_spreads_by_the_random_walk_variance() {
    let g = grid([6.0, 6.0], "", 0.05);
    let mut b = Belief::gaussian(g, [3.01, 3.01], 0.01);
    let before = b.estimate().covariance;
    b.predict(
        &RandomWalk {
            sigma_per_sqrt_s: 0.5,
        },
        1.0,
    )
    .unwrap();
    let after = b.estimate().covariance;
    assert_abs_diff_eq!(after[0][0] - before[0][0], 0.25, epsilon = 0.25 * 1e-3);
    assert_abs_diff_eq!(after[1][1] - before[1][1], 0.25, epsilon = 0.25 * 1e-3);
    assert_abs_diff_eq!(after[0][1], 0.0, epsilon = 1e-9);
}

/// Prior N(μ0, σ0²) times likelihood N(z, σz²) along a one-cell-wide corridor is the analytic
/// product: mean (μ0/σ0² + z/σz²)/(1/σ0² + 1/σz²), variance 1/(1/σ0² + 1/σz²).
#[test]
fn correction_matches_the_gaussian_product() {
    let cell = 0.01;
    let g = grid([10.0, cell], "", cell);
    assert_eq!(g.shape(), (1000, 1));
    let (mu0, s0, z, sz) = (4.0, 0.8, 5.0, 0.5);
    let mut b = Belief::gaussian(g.clone(), [mu0, 0.5 * cell], s0);
    let lik: Vec<f64> = (0..g.len())
        .map(|k| {
            let x = g.centre_of(k)[0];
            (-0.5 * (x - z).powi(2) / (sz * sz)).exp()
        })
        .collect();
    assert_eq!(b.correct(&lik).unwrap(), Correction::Applied);
    let (p0, pz) = (1.0 / (s0 * s0), 1.0 / (sz * sz));
    let mean = (mu0 * p0 + z * pz) / (p0 + pz);
    let var = 1.0 / (p0 + pz);
    let e = b.estimate();
    assert_abs_diff_eq!(e.mean[0], mean, epsilon = 1e-4);
    assert_abs_diff_eq!(e.covariance[0][0] - cell * cell / 12.0, var, epsilon = var * 1e-3);
    assert_abs_diff_eq!(e.most_likely[0], mean, epsilon = cell);
    let total: f64 = b.mass().iter().sum();
    assert_abs_diff_eq!(total, 1.0, epsilon = 1e-12);
}

#[test]
fn a_vanishing_product_resets_and_never_gives_nan() {
    let g = grid([4.0, 3.0], "", 0.1);
    let mut b = Belief::gaussian(g.clone(), [0.5, 0.5], 0.05);
    // The likelihood lives only where the prior has underflowed to zero.
    let lik: Vec<f64> = (0..g.len())
        .map(|k| if g.centre_of(k)[0] > 3.0 { 1e-300 } else { 0.0 })
        .collect();
    assert_eq!(b.correct(&lik).unwrap(), Correction::ResetToLikelihood);
    assert!(b.mass().iter().all(|m| m.is_finite()));
    assert!(b.estimate().mean[0] > 3.0);
    assert_eq!(
        b.correct(&vec![0.0; g.len()]).unwrap(),
        Correction::ResetToUniform
    );
    let u = 1.0 / g.free_count() as f64;
    assert!(b.mass().iter().all(|m| (*m - u).abs() < 1e-15));
    let e = b.estimate();
    assert!(e.mean.iter().all(|v| v.is_finite()));
}

#[test]
fn bad_likelihoods_and_steps_are_refused_without_change() {
    let g = grid([4.0, 3.0], "", 0.5);
    let mut b = Belief::gaussian(g.clone(), [1.0, 1.0], 0.5);
    let before = b.mass().to_vec();
    let mut lik = vec![1.0; g.len()];
    lik[3] = f64::NAN;
    assert!(b.correct(&lik).unwrap_err().to_string().contains("cell 3"));
    lik[3] = -1.0;
    assert!(b.correct(&lik).is_err());
    assert!(b.correct(&[1.0; 3]).unwrap_err().to_string().contains("3 cells"));
    assert!(b.predict(&WALK, -1.0).is_err());
    assert!(
        b.predict(
            &RandomWalk {
                sigma_per_sqrt_s: f64::INFINITY
            },
            1.0
        )
        .is_err()
    );
    assert_eq!(b.mass(), &before[..]);
}

/// Mean, covariance and most likely cell of a two-cell belief, by hand.
#[test]
fn estimate_and_heat_map_by_hand() {
    let g = grid([2.0, 1.0], "", 1.0);
    let mut b = Belief::uniform(g);
    b.mass.copy_from_slice(&[0.25, 0.75]);
    let e = b.estimate();
    // Centres 0.5 and 1.5: mean 1.25, variance 0.25·0.75 + 1/12.
    assert_abs_diff_eq!(e.mean[0], 1.25, epsilon = 1e-12);
    assert_abs_diff_eq!(e.mean[1], 0.5, epsilon = 1e-12);
    assert_abs_diff_eq!(e.covariance[0][0], 0.1875 + 1.0 / 12.0, epsilon = 1e-12);
    assert_abs_diff_eq!(e.covariance[1][1], 1.0 / 12.0, epsilon = 1e-12);
    assert_eq!(e.most_likely_cell, (1, 0));
    assert_eq!(e.most_likely, [1.5, 0.5]);
    let h = b.heat_map();
    assert_eq!((h.nx, h.ny, h.values.clone()), (2, 1, vec![0.25f32, 0.75]));
    // Entropy of {¼, ¾} on unit cells: −(¼ ln ¼ + ¾ ln ¾).
    assert_abs_diff_eq!(b.differential_entropy(), 0.562_335_144, epsilon = 1e-8);
}
