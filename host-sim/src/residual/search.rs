//! The forward selection's search (see [`mod@super::select`]): an orthonormal
//! basis of the model's columns on the fitting rows, the residual and every
//! candidate orthogonal to it, each candidate's error reduction ratio, and
//! the pick of the best one.

use super::outcome::ModelFit;
use super::select::COLLINEAR_REL;
use super::split::{dot, residual, Split};

/// The forward selection's state: the model so far, an orthonormal basis of
/// its columns on the fitting rows (modified Gram-Schmidt, re-orthogonalised
/// once), and the residual and the candidates orthogonal to it.
pub(super) struct Search {
    basis: Vec<Vec<f64>>,
    /// The fitting target orthogonal to the model.
    r: Vec<f64>,
    /// Each candidate orthogonal to the model (usable ones only).
    perp: Vec<Vec<f64>>,
    /// Each candidate's own norm.
    norms0: Vec<f64>,
    /// Finite on every fitting and validation row, not flat.
    pub(super) usable: Vec<bool>,
    pub(super) chosen: Vec<usize>,
    pub(super) names: Vec<String>,
    pub(super) current: ModelFit,
    pub(super) params: Vec<f64>,
    /// The current model's validation residual, row by row.
    pub(super) current_e: Vec<f64>,
}

/// Remove from `v` its parts along every vector of `basis`, twice.
fn project_out(v: &mut [f64], basis: &[Vec<f64>]) {
    for _ in 0..2 {
        for q in basis {
            let a = dot(v, q);
            v.iter_mut().zip(q).for_each(|(x, qk)| *x -= a * qk);
        }
    }
}

impl Search {
    pub(super) fn new(
        fit: &Split,
        val: &Split,
        names: Vec<String>,
        baseline: ModelFit,
        base_params: Vec<f64>,
    ) -> Self {
        let usable: Vec<bool> = (0..fit.cand.len())
            .map(|k| {
                fit.cand[k]
                    .iter()
                    .chain(&val.cand[k])
                    .all(|v| v.is_finite())
                    && dot(&fit.cand[k], &fit.cand[k]) > 0.0
            })
            .collect();
        let mut basis: Vec<Vec<f64>> = Vec::new();
        for c in &fit.base {
            let mut v = c.clone();
            let n0 = dot(&v, &v).sqrt();
            project_out(&mut v, &basis);
            let n = dot(&v, &v).sqrt();
            if n > COLLINEAR_REL * n0 && n > 0.0 {
                v.iter_mut().for_each(|x| *x /= n);
                basis.push(v);
            }
        }
        let mut r = fit.y.clone();
        project_out(&mut r, &basis);
        let mut perp: Vec<Vec<f64>> = fit.cand.clone();
        let norms0: Vec<f64> = fit.cand.iter().map(|c| dot(c, c).sqrt()).collect();
        for (k, w) in perp.iter_mut().enumerate() {
            if usable[k] {
                project_out(w, &basis);
            }
        }
        let current_e = residual(val, &[], &base_params);
        Self {
            basis,
            r,
            perp,
            norms0,
            usable,
            chosen: Vec::new(),
            names,
            current: baseline,
            params: base_params,
            current_e,
        }
    }

    /// Each candidate's error reduction ratio against the current residual
    /// (`None` for one not usable, set aside, chosen or collinear with the
    /// model); `None` when the residual is zero.
    pub(super) fn error_reduction_ratios(&self, set_aside: &[bool]) -> Option<Vec<Option<f64>>> {
        let rr = dot(&self.r, &self.r);
        if rr <= 0.0 {
            return None;
        }
        let mut errs: Vec<Option<f64>> = vec![None; self.perp.len()];
        for (k, e) in errs.iter_mut().enumerate() {
            if !self.usable[k] || set_aside[k] || self.chosen.contains(&k) {
                continue;
            }
            let nn = dot(&self.perp[k], &self.perp[k]);
            if nn.is_nan() || nn.sqrt() <= COLLINEAR_REL * self.norms0[k] {
                continue;
            }
            let err = dot(&self.perp[k], &self.r).powi(2) / (nn * rr);
            if err.is_finite() {
                *e = Some(err);
            }
        }
        Some(errs)
    }

    /// The error reduction ratio of the candidates `members` taken together
    /// (one effect of several columns, [`effect_groups`](super::library::effect_groups)):
    /// the share of the current residual's energy that the span of their
    /// parts orthogonal to the model explains. `None` when a member is not
    /// usable or already chosen, when the members are collinear with the
    /// model or with each other, or when the residual is zero.
    pub(super) fn group_err(&self, members: &[usize]) -> Option<f64> {
        let rr = dot(&self.r, &self.r);
        if rr <= 0.0
            || members
                .iter()
                .any(|&k| !self.usable[k] || self.chosen.contains(&k))
        {
            return None;
        }
        let mut own: Vec<Vec<f64>> = Vec::with_capacity(members.len());
        let mut explained = 0.0;
        for &k in members {
            let mut v = self.perp[k].clone();
            project_out(&mut v, &own);
            let n = dot(&v, &v).sqrt();
            if n.is_nan() || n <= COLLINEAR_REL * self.norms0[k] {
                return None;
            }
            v.iter_mut().for_each(|x| *x /= n);
            explained += dot(&v, &self.r).powi(2);
            own.push(v);
        }
        let err = explained / rr;
        err.is_finite().then_some(err)
    }

    /// Take candidate `k` into the model: its fit, its parameters, its runs'
    /// errors; the residual and the other candidates lose their part along it.
    pub(super) fn accept(
        &mut self,
        k: usize,
        names: Vec<String>,
        fit: ModelFit,
        params: Vec<f64>,
        e: Vec<f64>,
    ) {
        self.current_e = e;
        self.chosen.push(k);
        self.names = names;
        self.current = fit;
        self.params = params;
        let mut q = self.perp[k].clone();
        let n = dot(&q, &q).sqrt();
        q.iter_mut().for_each(|x| *x /= n);
        let a = dot(&self.r, &q);
        self.r.iter_mut().zip(&q).for_each(|(x, qk)| *x -= a * qk);
        self.basis.push(q);
        let last = self.basis.len() - 1;
        for (j, w) in self.perp.iter_mut().enumerate() {
            if self.usable[j] && !self.chosen.contains(&j) {
                project_out(w, &self.basis[last..]);
            }
        }
    }
}

/// The candidate with the largest ratio, the first of equals (outside
/// `skip_class` when given).
pub(super) fn best(
    errs: &[Option<f64>],
    classes: &[String],
    skip_class: Option<&str>,
) -> Option<(usize, f64)> {
    first_max(
        errs.iter()
            .enumerate()
            .filter(|(k, _)| skip_class.is_none_or(|c| classes[*k] != c))
            .filter_map(|(k, e)| e.map(|e| (k, e))),
    )
}

/// The `(index, ratio)` with the largest ratio, the first of equals.
pub(super) fn first_max(items: impl Iterator<Item = (usize, f64)>) -> Option<(usize, f64)> {
    items.fold(None, |b: Option<(usize, f64)>, (k, e)| {
        if b.is_none_or(|(_, be)| e > be) {
            Some((k, e))
        } else {
            b
        }
    })
}
