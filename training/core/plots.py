"""matplotlib for the training side's figures, headless (no display on the training machines)."""
from __future__ import annotations


def pyplot():
    """matplotlib.pyplot on the Agg backend."""
    import matplotlib  # here, not at the top: the backend must be chosen before pyplot loads, and only plots pay for it
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after use("Agg") above
    return plt
