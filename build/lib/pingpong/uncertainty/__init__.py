"""Uncertainty of the strike-point predictions: the paper's four estimators, conformal intervals
with a coverage guarantee, and the metrics that say whether an uncertainty is informative."""
