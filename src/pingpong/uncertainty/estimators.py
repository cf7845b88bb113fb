"""Every uncertainty estimator of the strike point, registered by name (registry.py has the interface).

Parts (DATASET's split, by rally): the k-NN regressor, the quantile heads and the error head learn
from the training hits' out-of-fold errors; every conformal quantile and the time-to-hit trend come from the
calibration hits (grouped by hit, see conformal.py); the estimators are applied to the calibration
and test hits. Every estimator scores the same point predictions (the final model's), so their
errors are shared and only the uncertainty differs.

The models that need torch or scipy are imported on first use (Learned.models): the workflow
imports this module for the names alone (the code hash still follows those imports).
"""

import numpy as np

from pingpong.frames import N_INPUT
from pingpong.uncertainty.conformal import (
    conformal_quantile,
    cqr_scores,
    mondrian_quantiles,
    normalised_scores,
)
from pingpong.uncertainty.registry import Band, Estimator, Hits, register
from pingpong.uncertainty.time_to_hit import fit_trend, trend

DIFFICULTY_FLOOR = 0.1  # sigma = difficulty + this share of its calibration median: no zero widths
BALL_RATE = slice(2 * N_INPUT - 3, 2 * N_INPUT)  # frame_features: the ball velocity (m/s) at the frame
MAX_SPEED_BINS = 3  # the Mondrian context: up to terciles of the incoming ball's speed
PREDICTED = ["a1", "a2", "b", "strike_x_pred"]  # the prediction's columns that the quantile heads read


def _interval(pred: np.ndarray, half: np.ndarray) -> Band:
    return Band(half, pred - half, pred + half)


def _per_row(by_key: dict, keys) -> np.ndarray:
    """Each row's value of a per-frame (or per-cell) table; a key calibration never reached has no
    quantile: +inf, an infinite interval, as conformal_quantile gives for too few hits."""
    return np.array([by_key.get(k, np.inf) for k in keys])


def _to_json(by_key: dict) -> dict:
    """A table keyed by frame (or cell) as JSON: string keys."""
    return {str(k): v for k, v in by_key.items()}


def _from_json(by_key: dict) -> dict:
    return {int(k): v for k, v in by_key.items()}


@register
class Ensemble(Estimator):
    """The paper's: the std of the members' strike points (the final model's seeds; their mean predicts)."""

    name, paper = "ensemble", True

    def apply(self, hits: Hits) -> Band:
        return Band(hits.ensemble_spread, std=hits.ensemble_spread)


@register
class Conformal(Estimator):
    """The paper's split conformal: one quantile of the calibration errors, one width for every row."""

    name, paper = "conformal", True

    def fit(self, hits, fitted, rng):
        cal = hits.calibration
        self.quantile = conformal_quantile(hits.abs_error[cal], self.alpha, hits.groups[cal])

    def apply(self, hits):
        return _interval(hits.pred, np.full(len(hits.rows), self.quantile))

    def state(self):
        return {"quantile": self.quantile}

    def restore(self, state, model_stem, fitted):
        self.quantile = state["quantile"]


class Learned(Estimator):
    """An estimator with a learned model; `models()` is the module that fits it and saves and loads it
    (`save(model, stem, prov)`, `load(stem)`), imported on first use."""

    @staticmethod
    def models():
        raise NotImplementedError

    def save_model(self, stem, prov):
        self.models().save(self.model, stem, prov)

    def restore(self, state, model_stem, fitted):
        self.model = self.models().load(model_stem)


@register
class Knn(Learned):
    """The paper's k-NN regressor of the absolute error from the inputs (knn.py)."""

    name, paper, model_file = "knn", True, "knn"

    @staticmethod
    def models():
        from pingpong.uncertainty import knn

        return knn

    def fit(self, hits, fitted, rng):
        train = hits.train
        self.model = self.models().fit_knn(hits.features[train], hits.abs_error[train], self.settings.knn_k)

    def apply(self, hits):
        return Band(self.models().predict_knn(self.model, hits.features))

    def state(self):
        return {"k": self.model.k}


@register
class TimeToHit(Estimator):
    """The paper's time-to-hit: the calibration errors' linear trend over the frames before the hit."""

    name, paper = "time_to_hit", True

    def fit(self, hits, fitted, rng):
        cal = hits.calibration
        self.intercept, self.slope = fit_trend(hits.frames[cal], hits.abs_error[cal])

    def apply(self, hits):
        return Band(trend(self.intercept, self.slope, hits.frames))

    def state(self):
        return {"intercept": self.intercept, "slope": self.slope}

    def restore(self, state, model_stem, fitted):
        self.intercept, self.slope = state["intercept"], state["slope"]


@register
class ErrorHead(Learned):
    """A small GRU that reads the inputs and the prediction and learns the training hits' out-of-fold
    errors (error_head.py)."""

    name, model_file = "error_head", "error_head"

    @staticmethod
    def models():
        from pingpong.uncertainty import error_head

        return error_head

    def fit(self, hits, fitted, rng):
        train = hits.by_hit(hits.train)[:, 0]  # a hit's rows share its split
        pred, err = hits.by_hit(hits.pred), hits.by_hit(hits.abs_error)
        self.model = self.models().fit_error_head(hits.X[train], pred[train], err[train], rng,
                                                  hidden=self.settings.error_head_hidden,
                                                  epochs=self.settings.error_head_epochs)

    def apply(self, hits):
        return Band(self.models().predict_error(self.model, hits.X, hits.by_hit(hits.pred)).reshape(-1))


@register
class Mondrian(Estimator):
    """Mondrian conformal: one quantile per frame before the hit."""

    name = "mondrian"

    def fit(self, hits, fitted, rng):
        cal = hits.calibration
        self.by_frame = mondrian_quantiles(hits.abs_error[cal], hits.frames[cal], self.alpha,
                                           hits.groups[cal])

    def apply(self, hits):
        return _interval(hits.pred, _per_row(self.by_frame, hits.frames))

    def state(self):
        return {"quantile_by_frame": _to_json(self.by_frame)}

    def restore(self, state, model_stem, fitted):
        self.by_frame = _from_json(state["quantile_by_frame"])


@register
class EnsembleTime(Estimator):
    """The follow-up work's normalised split conformal per frame: scores |y - y_hat| / (std + c t) with
    std the ensemble spread and t the frames before the hit, one quantile per frame. c (m per frame)
    is the slope of the training hits' out-of-fold errors over t (clipped at 0), so the calibration
    hits are left for the quantiles alone."""

    name = "ensemble_time"

    def _sigma(self, hits):
        return hits.ensemble_spread + self.c * hits.frames + 1e-6

    def fit(self, hits, fitted, rng):
        train, cal = hits.train, hits.calibration
        self.c = max(fit_trend(hits.frames[train], hits.abs_error[train])[1], 0.0)
        scores = normalised_scores(hits.abs_error, self._sigma(hits))
        self.by_frame = mondrian_quantiles(scores[cal], hits.frames[cal], self.alpha, hits.groups[cal])

    def apply(self, hits):
        return _interval(hits.pred, _per_row(self.by_frame, hits.frames) * self._sigma(hits))

    def state(self):
        return {"c": self.c, "quantile_by_frame": _to_json(self.by_frame)}

    def restore(self, state, model_stem, fitted):
        self.c = state["c"]
        self.by_frame = _from_json(state["quantile_by_frame"])


@register
class MondrianSpeed(Estimator):
    """Mondrian conformal by frame and by a context the inputs reveal: the bin of the incoming ball's
    speed at that frame (the time pressure a fast ball puts on the player), one quantile of |y - y_hat|
    per (frame, bin) cell. Each frame's bin edges are quantiles of its training rows, so a cell holds
    about 1 / n_bins of the calibration hits.

    n_bins (up to terciles) is set by the number of calibration hits alone, before any score is seen: a
    cell needs (1 - alpha) / alpha hits for a finite quantile (9 at alpha 0.1), and the bins are as many
    as leave the mean cell twice that. The calibration hits fall into training-made bins unevenly: with
    terciles, the default run's 41 calibration hits (13.7 a cell) left 3 of 93 cells under 9 hits and
    their intervals infinite; halves hold 20.5 on average, 9 lies 3.6 binomial standard deviations below.
    """

    name = "mondrian_speed"

    def _cells(self, hits):
        speed = np.linalg.norm(hits.features[:, BALL_RATE], axis=1)
        bins = [np.searchsorted(self.edges[f], s) for f, s in zip(hits.frames, speed, strict=True)]
        return hits.frames * MAX_SPEED_BINS + np.asarray(bins, int)

    def fit(self, hits, fitted, rng):
        speed = np.linalg.norm(hits.features[:, BALL_RATE], axis=1)
        n_cal = len(np.unique(hits.groups[hits.calibration]))
        smallest_cell = int(np.ceil((1 - self.alpha) / self.alpha - 1e-9))
        n_bins = int(np.clip(n_cal // (2 * smallest_cell), 1, MAX_SPEED_BINS))
        levels = np.arange(1, n_bins) / n_bins
        self.edges = {int(f): np.quantile(speed[hits.train & (hits.frames == f)], levels)
                      for f in np.unique(hits.frames)}
        cal = hits.calibration
        self.by_cell = mondrian_quantiles(hits.abs_error[cal], self._cells(hits)[cal], self.alpha,
                                          hits.groups[cal])

    def apply(self, hits):
        return _interval(hits.pred, _per_row(self.by_cell, self._cells(hits)))

    def state(self):
        return {"speed_edges_m_s": {str(f): e.tolist() for f, e in self.edges.items()},
                "quantile_by_cell": _to_json(self.by_cell)}

    def restore(self, state, model_stem, fitted):
        self.edges = {int(f): np.asarray(e) for f, e in state["speed_edges_m_s"].items()}
        self.by_cell = _from_json(state["quantile_by_cell"])


class Normalised(Estimator):
    """Normalised conformal on another estimator's uncertainty (the difficulty): |y - y_hat| / sigma,
    sigma = difficulty + a floor of DIFFICULTY_FLOOR times its calibration median."""

    base: str

    def fit(self, hits, fitted, rng):
        self.difficulty = fitted[self.base]
        cal = hits.calibration
        difficulty = self.difficulty.apply(hits).uncertainty
        self.floor = DIFFICULTY_FLOOR * float(np.median(difficulty[cal]))
        sigma = difficulty + self.floor
        self.quantile = conformal_quantile(normalised_scores(hits.abs_error[cal], sigma[cal]), self.alpha,
                                           hits.groups[cal])

    def apply(self, hits):
        return _interval(hits.pred, self.quantile * (self.difficulty.apply(hits).uncertainty + self.floor))

    def state(self):
        return {"quantile": self.quantile, "floor": self.floor}

    def restore(self, state, model_stem, fitted):
        self.difficulty, self.quantile, self.floor = fitted[self.base], state["quantile"], state["floor"]


@register
class NormalisedKnn(Normalised):
    name, base = "normalised_knn", "knn"


@register
class NormalisedEnsemble(Normalised):
    name, base = "normalised_ensemble", "ensemble"


@register
class NormalisedErrorHead(Normalised):
    name, base = "normalised_error_head", "error_head"


@register
class Cqr(Learned):
    """Conformalised quantile regression (Romano et al. 2019) on quantile heads of the residual that read
    the row's features and the prediction (quantile_heads.py)."""

    name, model_file = "cqr", "quantile_heads"

    @staticmethod
    def models():
        from pingpong.uncertainty import quantile_heads

        return quantile_heads

    @staticmethod
    def _inputs(hits):
        return np.hstack([hits.features, hits.rows[PREDICTED].to_numpy(float)])

    def _quantiles(self, hits):
        return hits.pred[:, None] + self.models().predict_quantiles(self.model, self._inputs(hits))

    def fit(self, hits, fitted, rng):
        train, cal = hits.train, hits.calibration
        self.model = self.models().fit_quantile_heads(
            self._inputs(hits)[train], (hits.y - hits.pred)[train], (self.alpha / 2, 1 - self.alpha / 2), rng,
            hidden=self.settings.quantile_hidden, epochs=self.settings.quantile_epochs)
        quantiles = self._quantiles(hits)
        self.quantile = conformal_quantile(cqr_scores(hits.y[cal], quantiles[cal, 0], quantiles[cal, 1]),
                                           self.alpha, hits.groups[cal])

    def apply(self, hits):
        quantiles = self._quantiles(hits)
        lower, upper = quantiles[:, 0] - self.quantile, quantiles[:, 1] + self.quantile
        return Band((upper - lower) / 2, lower, upper)

    def state(self):
        return {"quantile": self.quantile, "levels": list(self.model.levels)}

    def restore(self, state, model_stem, fitted):
        super().restore(state, model_stem, fitted)
        self.quantile = state["quantile"]


@register
class Hetero(Learned):
    """The heteroscedastic head alone (hetero_head.py, beta-NLL): the residual's std, and the Gaussian
    central interval around the bias-corrected prediction, uncalibrated."""

    name, model_file = "hetero", "hetero_head"

    @staticmethod
    def models():
        from pingpong.uncertainty import hetero_head

        return hetero_head

    def fit(self, hits, fitted, rng):
        train = hits.by_hit(hits.train)[:, 0]  # a hit's rows share its split
        pred, residual = hits.by_hit(hits.pred), hits.by_hit(hits.y - hits.pred)
        self.model = self.models().fit_hetero_head(hits.X[train], pred[train], residual[train], rng,
                                                   hidden=self.settings.hetero_hidden,
                                                   epochs=self.settings.hetero_epochs)

    def mean_std(self, hits) -> tuple[np.ndarray, np.ndarray]:
        """(bias-corrected centre, std) per row, m."""
        mean, std = self.models().predict_hetero(self.model, hits.X, hits.by_hit(hits.pred))
        return hits.pred + mean.reshape(-1), std.reshape(-1)

    def apply(self, hits):
        centre, std = self.mean_std(hits)
        half = self.z * std
        return Band(std, centre - half, centre + half, std=std)


class OnHetero(Estimator):
    """A conformal method around the heteroscedastic head's (centre, std), one quantile per frame."""

    def fit(self, hits, fitted, rng):
        self.hetero = fitted[Hetero.name]
        centre, std = self.hetero.mean_std(hits)
        cal = hits.calibration
        scores = self.scores(hits.y, centre, std)
        self.by_frame = mondrian_quantiles(scores[cal], hits.frames[cal], self.alpha, hits.groups[cal])

    def apply(self, hits):
        centre, std = self.hetero.mean_std(hits)
        lower, upper = self.bounds(centre, std, _per_row(self.by_frame, hits.frames))
        return Band((upper - lower) / 2, lower, upper)

    def state(self):
        return {"quantile_by_frame": _to_json(self.by_frame)}

    def restore(self, state, model_stem, fitted):
        self.hetero = fitted[Hetero.name]
        self.by_frame = _from_json(state["quantile_by_frame"])


@register
class NormalisedHetero(OnHetero):
    """Normalised conformal on the head's std: scores |y - centre| / std, the interval centre +- q std."""

    name = "normalised_hetero"

    @staticmethod
    def scores(y, centre, std):
        return normalised_scores(np.abs(y - centre), std)

    @staticmethod
    def bounds(centre, std, q):
        return centre - q * std, centre + q * std


@register
class CqrHetero(OnHetero):
    """CQR (Romano et al. 2019) on the head's Gaussian quantiles centre -+ z std: scores how far y lies
    outside them, the interval widened (or narrowed) by q on each side."""

    name = "cqr_hetero"

    def _quantiles(self, centre, std):
        half = self.z * std
        return centre - half, centre + half

    def scores(self, y, centre, std):
        return cqr_scores(y, *self._quantiles(centre, std))

    def bounds(self, centre, std, q):
        lower, upper = self._quantiles(centre, std)
        return lower - q, upper + q


@register
class Clear(Estimator):
    """Aleatoric plus epistemic, calibrated in two parts (after CLEAR, Azizi et al., ICLR 2026): the
    half-width gamma_f (std_aleatoric + lambda std_epistemic), std_aleatoric the heteroscedastic head's,
    std_epistemic the ensemble spread, around the head's bias-corrected centre. lambda (their balance)
    is the grid value whose calibrated intervals have the lowest Winkler score on the first half of the
    calibration hits; gamma_f (the scale, per frame) is the conformal quantile of the normalised scores of
    the other half, so the quantile's guarantee is untouched by the choice of lambda."""

    name = "clear"
    LAMBDAS = (0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0)

    def _parts(self, hits):
        """(centre, aleatoric std, epistemic std) per row, m."""
        centre, aleatoric = self.hetero.mean_std(hits)
        return centre, aleatoric, hits.ensemble_spread

    def fit(self, hits, fitted, rng):
        from pingpong.uncertainty.metrics import winkler_score  # scipy: not on the workflow's import path

        self.hetero = fitted[Hetero.name]
        centre, aleatoric, epistemic = self._parts(hits)
        residual = np.abs(hits.y - centre)

        def gamma(rows, lam):
            scores = normalised_scores(residual, aleatoric + lam * epistemic)
            return mondrian_quantiles(scores[rows], hits.frames[rows], self.alpha, hits.groups[rows])

        def winkler(rows, lam):
            half = _per_row(gamma(rows, lam), hits.frames[rows]) * (aleatoric + lam * epistemic)[rows]
            return winkler_score(hits.y[rows], centre[rows] - half, centre[rows] + half, self.alpha)

        cal_hits = np.unique(hits.groups[hits.calibration])
        choose = np.isin(hits.groups, cal_hits[: len(cal_hits) // 2])
        self.lam = min(self.LAMBDAS, key=lambda lam: winkler(choose, lam))
        self.by_frame = gamma(hits.calibration & ~choose, self.lam)

    def apply(self, hits):
        centre, aleatoric, epistemic = self._parts(hits)
        return _interval(centre, _per_row(self.by_frame, hits.frames) * (aleatoric + self.lam * epistemic))

    def state(self):
        return {"lambda": self.lam, "gamma_by_frame": _to_json(self.by_frame)}

    def restore(self, state, model_stem, fitted):
        self.hetero, self.lam = fitted[Hetero.name], state["lambda"]
        self.by_frame = _from_json(state["gamma_by_frame"])
