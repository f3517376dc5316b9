//! The seed's pruning by `%sigma` (Sect. 4.2).

use anyhow::{bail, Context, Result};
use cable_joint::lsq::Fit;

use super::design::{solve, Design};
use super::{
    nonnegative_by_physics, physically_required, IdentOptions, ModelTerm, Regressor, MAX_REGRESSORS,
};

/// What the pruning kept and dropped.
pub(super) struct Pruned {
    /// Kept columns of the design.
    pub(super) active: Vec<usize>,
    /// The fit on them.
    pub(super) fit: Fit<MAX_REGRESSORS>,
    /// Dropped regressors with their `%sigma` when dropped, in order (a
    /// term of forbidden sign can go with a `%sigma` below the limit).
    pub(super) dropped: Vec<(Regressor, f64)>,
}

/// The seed's pruning of a fit on all columns of `d` (see the module
/// documentation and [`IdentOptions::prune_all_at_once`]). The spring
/// `K_s x2`, the preload `F_0` (and the JAE's `c4 x2`) and the guides'
/// Coulomb terms are physics the model cannot do without
/// ([`physically_required`]): they are never pruned, whatever their
/// `%sigma` (a poorly excited run says so in the fit's table instead).
///
/// A term whose value has a sign physics forbids (a negative mass, damping
/// or friction coefficient, [`nonnegative_by_physics`]) is dropped like one
/// above the `%sigma` limit, before any of those: a well-determined
/// negative mass is a correlation with something the model lacks, not an
/// effect, and keeping it would fit a term the core does not evaluate.
pub(super) fn prune(
    d: &Design,
    terms: &[ModelTerm],
    first: Fit<MAX_REGRESSORS>,
    opts: &IdentOptions,
) -> Result<Pruned> {
    let mut dropped: Vec<(Regressor, f64)> = Vec::new();
    let mut active: Vec<usize> = (0..terms.len()).collect();
    let mut fit = first;
    let pct = |fit: &Fit<MAX_REGRESSORS>, k: usize| {
        let p = fit.pct_sigma(k);
        if p.is_nan() {
            f64::INFINITY
        } else {
            p
        }
    };
    // The order of dropping: a forbidden sign first, then the `%sigma`.
    let badness = |fit: &Fit<MAX_REGRESSORS>, k: usize, r: Regressor| {
        if nonnegative_by_physics(r) && fit.params[k] < 0.0 {
            f64::INFINITY
        } else {
            pct(fit, k)
        }
    };
    if opts.prune_all_at_once {
        // The seed: every parameter above the limit at once, then refit.
        let mut next = Vec::new();
        for (k, j) in active.iter().enumerate() {
            let p = pct(&fit, k);
            let bad = badness(&fit, k, terms[*j].regressor);
            if bad > opts.max_pct_sigma && !physically_required(terms[*j].regressor) {
                dropped.push((terms[*j].regressor, p));
            } else {
                next.push(*j);
            }
        }
        if next.is_empty() {
            bail!(
                "pruning at {} % dropped every regressor",
                opts.max_pct_sigma
            );
        }
        if next.len() < active.len() {
            active = next;
            fit = solve(d, &active, opts).context("refitting the pruned model")?;
        }
    }
    // Backward elimination: drop the worst while one is above the limit
    // (or of a forbidden sign; among those the one of largest `%sigma`).
    loop {
        let worst = (0..active.len())
            .filter(|k| !physically_required(terms[active[*k]].regressor))
            .map(|k| {
                (
                    k,
                    badness(&fit, k, terms[active[k]].regressor),
                    pct(&fit, k),
                )
            })
            .filter(|(_, bad, _)| *bad > opts.max_pct_sigma)
            .max_by(|a, b| a.1.total_cmp(&b.1).then(a.2.total_cmp(&b.2)));
        let Some((k, _, p)) = worst else { break };
        dropped.push((terms[active[k]].regressor, p));
        active.remove(k);
        if active.is_empty() {
            bail!(
                "pruning at {} % dropped every regressor",
                opts.max_pct_sigma
            );
        }
        fit = solve(d, &active, opts).context("refitting the pruned model")?;
    }
    Ok(Pruned {
        active,
        fit,
        dropped,
    })
}

#[cfg(test)]
mod tests {
    use super::super::term;
    use super::*;
    use crate::stats::test_rng::Rng;

    const TERMS: [ModelTerm; 5] = [
        term(Regressor::SgnX1Vel, "f_sc1", "N"),
        term(Regressor::SgnX2Vel, "f_cp2", "N"),
        term(Regressor::X2, "K_s", "N/m"),
        term(Regressor::One, "F_0", "N"),
        term(Regressor::X1Acc, "m_0", "kg"),
    ];

    /// `y = 6 s1 + 2 s2 + 650 x2 + 19.5 + noise n`, with `s2` equal to `s1`
    /// except on `split` of the rows, and a junk column (`x1''`-like) that
    /// does not enter `y`.
    fn design(split: usize, noise: f64, rng: &mut Rng) -> Design {
        let n = 4000;
        let mut d = Design {
            cols: vec![Vec::new(); 5],
            y: Vec::new(),
        };
        for k in 0..n {
            let t = k as f64 * 1e-3;
            let s1 = if (t * 3.0).sin() >= 0.0 { 1.0 } else { -1.0 };
            let s2 = if k % (n / split.max(1)) < 1 && split > 0 {
                -s1
            } else {
                s1
            };
            let x2 = 3e-3 * (t * 1.3).sin();
            let junk = 1e-3 * rng.normal();
            let y = 6.0 * s1 + 2.0 * s2 + 650.0 * x2 + 19.5 + noise * rng.normal();
            for (c, v) in d.cols.iter_mut().zip([s1, s2, x2, 1.0, junk]) {
                c.push(v);
            }
            d.y.push(y);
        }
        d
    }

    fn kept(d: &Design, opts: &IdentOptions) -> (Vec<Regressor>, Fit<MAX_REGRESSORS>) {
        let all: Vec<usize> = (0..TERMS.len()).collect();
        let first = solve(d, &all, opts).unwrap();
        let p = prune(d, &TERMS, first, opts).unwrap();
        (
            p.active.iter().map(|j| TERMS[*j].regressor).collect(),
            p.fit,
        )
    }

    #[test]
    fn pruning_drops_the_junk_and_keeps_the_physics() {
        let mut rng = Rng(0x1234_5678_9abc_def1);
        // s1 and s2 differ on 400 rows: both are determined.
        let d = design(400, 0.3, &mut rng);
        let opts = IdentOptions::default();
        let (kept, fit) = kept(&d, &opts);
        assert_eq!(
            kept,
            vec![
                Regressor::SgnX1Vel,
                Regressor::SgnX2Vel,
                Regressor::X2,
                Regressor::One
            ]
        );
        for (k, want) in [6.0, 2.0, 650.0, 19.5].iter().enumerate() {
            assert!(
                (fit.params[k] - want).abs() < 0.05 * want,
                "param {k}: {} vs {want}",
                fit.params[k]
            );
        }
    }

    /// The junk column (`x1''`, a mass) made to enter `y` with a negative
    /// coefficient, well determined: a negative mass goes whatever its
    /// `%sigma`; the same column with a positive coefficient stays.
    #[test]
    fn a_well_determined_negative_mass_is_dropped_and_a_positive_one_kept() {
        for (coef, kept_junk) in [(-2000.0, false), (2000.0, true)] {
            let mut rng = Rng(0x5eed);
            let mut d = design(400, 0.3, &mut rng);
            for (y, j) in d.y.iter_mut().zip(&d.cols[4]) {
                *y += coef * j;
            }
            let all: Vec<usize> = (0..TERMS.len()).collect();
            let first = solve(&d, &all, &IdentOptions::default()).unwrap();
            assert!(first.pct_sigma(4) < 5.0, "junk at {} %", first.pct_sigma(4));
            let (kept, _) = kept(&d, &IdentOptions::default());
            assert_eq!(
                kept.contains(&Regressor::X1Acc),
                kept_junk,
                "coefficient {coef}: kept {kept:?}"
            );
        }
    }

    /// Where the two rules part: a real viscous term `b x2'` (well
    /// determined alone) beside a junk column nearly collinear with it
    /// (`x1''` = `x2'` plus a little noise, correlation 0.9993). In the
    /// full fit both are above 5 %. One at a time drops the junk (the worse
    /// `%sigma`), after which `b` is pinned down and kept at its value; the
    /// seed's all-at-once rule drops both.
    #[test]
    fn one_at_a_time_keeps_a_term_that_all_at_once_drops_with_its_collinear_twin() {
        // TERMS with `b x2'` before the junk column.
        const TERMS6: [ModelTerm; 6] = [
            TERMS[0],
            TERMS[1],
            TERMS[2],
            TERMS[3],
            term(Regressor::X2Vel, "b", "N s/m"),
            TERMS[4],
        ];
        let mut rng = Rng(0xc011_1ea4);
        let mut d = design(400, 0.3, &mut rng);
        let (mut v, mut twin) = (Vec::new(), Vec::new());
        for (k, y) in d.y.iter_mut().enumerate() {
            let vel = 3.9e-3 * (k as f64 * 1.3e-3).cos();
            v.push(vel);
            twin.push(vel + 1e-4 * rng.normal());
            *y += 200.0 * vel;
        }
        d.cols[4] = v;
        d.cols.push(twin);
        let all: Vec<usize> = (0..TERMS6.len()).collect();
        let opts = IdentOptions::default();
        let first = solve(&d, &all, &opts).unwrap();
        assert!(first.pct_sigma(4) > 5.0 && first.pct_sigma(5) > 5.0);
        let one = prune(&d, &TERMS6, first.clone(), &opts).unwrap();
        let regs = |p: &Pruned| -> Vec<Regressor> {
            p.active.iter().map(|j| TERMS6[*j].regressor).collect()
        };
        assert!(regs(&one).contains(&Regressor::X2Vel), "{:?}", regs(&one));
        assert!(!regs(&one).contains(&Regressor::X1Acc), "{:?}", regs(&one));
        let b = one.fit.params[one.active.iter().position(|&j| j == 4).unwrap()];
        assert!((b - 200.0).abs() < 0.05 * 200.0, "b = {b}");
        let seed = IdentOptions {
            prune_all_at_once: true,
            ..IdentOptions::default()
        };
        let all_at_once = prune(&d, &TERMS6, first, &seed).unwrap();
        assert!(
            !regs(&all_at_once).contains(&Regressor::X2Vel)
                && !regs(&all_at_once).contains(&Regressor::X1Acc),
            "{:?}",
            regs(&all_at_once)
        );
    }

    #[test]
    fn collinear_friction_signs_are_kept_with_their_sum_determined() {
        let mut rng = Rng(42);
        // s1 and s2 differ on 4 rows only: each alone is poorly determined,
        // their sum (8 N) is not.
        let d = design(4, 2.0, &mut rng);
        let full = solve(&d, &[0, 1, 2, 3, 4], &IdentOptions::default()).unwrap();
        assert!(full.pct_sigma(0) > 5.0 && full.pct_sigma(1) > 5.0);
        for opts in [
            IdentOptions::default(),
            // The seed's all-at-once rule dropped both and lost the friction.
            IdentOptions {
                prune_all_at_once: true,
                ..IdentOptions::default()
            },
        ] {
            let (kept, fit) = kept(&d, &opts);
            assert_eq!(
                kept,
                vec![
                    Regressor::SgnX1Vel,
                    Regressor::SgnX2Vel,
                    Regressor::X2,
                    Regressor::One
                ],
                "the junk term goes, the guides' friction stays"
            );
            let sum = fit.params[0] + fit.params[1];
            assert!((sum - 8.0).abs() < 0.1, "friction sum {sum}");
        }
    }
}
