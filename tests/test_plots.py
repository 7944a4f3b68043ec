"""The run plot's mode shading (sim_hil/plots.py): one span per stretch of a mode, the last to the end."""
from __future__ import annotations

from sim_hil.plots import mode_spans, plot_heights_and_velocity


def test_modes_become_spans_that_end_where_the_next_begins():
    modes = [(0.0, "DAMPING"), (0.1, "PREPARE"), (0.2, "PREPARE"), (2.1, "POLICY"), (5.0, "POLICY"), (7.8, "FAULT")]
    assert mode_spans(modes, 10.0) == [(0.0, 0.1, "DAMPING"), (0.1, 2.1, "PREPARE"), (2.1, 7.8, "POLICY"),
                                       (7.8, 10.0, "FAULT")]
    assert mode_spans([], 10.0) == []


def test_the_plot_is_drawn_with_its_modes(tmp_path):
    series = {"student": {"t": [0.0, 1.0, 2.0], "trunk": [0.2, 0.4, 0.6], "waist": [0.1, 0.3, 0.5],
                          "vx": [0.0, 0.1, 0.2]}}
    path = plot_heights_and_velocity(series, tmp_path / "p.png", "t", command_vx=[(0.0, 0.0)],
                                     modes=[(0.0, "PREPARE"), (1.0, "POLICY"), (1.5, "FAULT")])
    assert path.stat().st_size > 0
