"""Which runs a report trusts: status ``ok`` and no finding of the health audit (a run
with warnings may be wrong, so it never counts as reaching an accuracy)."""

from __future__ import annotations

import pandas as pd


def ok_runs(runs: pd.DataFrame) -> pd.DataFrame:
    """The rows of status ``ok``."""
    return runs[runs["status"] == "ok"]


def warned(runs: pd.DataFrame) -> pd.Series:
    """True for the rows whose health audit found something (column ``warnings``)."""
    if "warnings" not in runs:
        return pd.Series(False, index=runs.index)
    return runs["warnings"].astype(object).fillna("").astype(str).str.len() > 0
