"""The picture of ``friction-sim sweep-report``: one row per slice, the mean
value over (x, y) and, when cells hold several parts, its spread beside it.

The no-motion boundary (half the parts of a cell at U = 0; with one part per
cell, the edge of the cells that do not move) is a red line with the region
hatched; the flight boundary (half the parts flying) a black dashed line.
When the sweep ran a calibrated plant (``plant_params: calibrated.yaml``),
a column more draws the width of each cell's 95 % band, the calibration's
uncertainty carried through the model
(:mod:`~friction_sim.experiment.calibration_bands`), with the same boundaries.
The figure comes from :mod:`friction_sim.cli.figures` (no pyplot state) and is
saved with its :func:`~friction_sim.cli.figures.save_figure`, at the same dpi
as every other figure; matplotlib is only imported there, when one is drawn.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from friction_sim.cli.figures import pyplot_free_figure as new_figure
from friction_sim.experiment.calibration_bands import SweepBands
from friction_sim.experiment.sweep_report import SweepMaps, finite_range

LABELS = {"mean_velocity": "mean speed V [m/s]", "U": "U = V f/(g mu)", "flight_fraction": "flight fraction",
          "stick_fraction": "stick fraction", "throw_number": r"throw number $\Gamma$",
          "excitation_angle": r"vibration angle $\beta$ [deg]", "track_inclination": r"inclination $\alpha$ [deg]",
          "mu": r"$\mu$", "excitation_amplitude": "$P_a$ [N]", "drive_force": "$F_d$ [N]"}


def _edges(centres: np.ndarray) -> np.ndarray:
    """Cell edges around sorted centres (half-way between neighbours)."""
    centres = np.asarray(centres, dtype=float)
    if centres.size == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    middle = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate([[2 * centres[0] - middle[0]], middle, [2 * centres[-1] - middle[-1]]])


def sweep_figure(maps: SweepMaps, bands: SweepBands | None = None) -> Any:
    """The maps as a Figure (see the module docstring); ``bands``: the calibrated
    plant's band in a column of its own (its width, mm/s)."""
    numeric = maps.x_values.dtype.kind in "fiu" and maps.y_values.dtype.kind in "fiu"
    columns = (2 if maps.parts > 1 else 1) + (1 if bands is not None else 0)
    rows = max(len(maps.slices), 1)
    fig = new_figure(figsize=(6.4 * columns, 4.2 * rows), layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False)
    low, high = finite_range([piece.mean for piece in maps.slices])
    symmetric = low < 0.0 < high
    limit = max(abs(low), abs(high))
    x_edges = _edges(np.arange(maps.x_values.size) if not numeric else maps.x_values)
    y_edges = _edges(np.arange(maps.y_values.size) if not numeric else maps.y_values)
    x = maps.x_values if numeric else np.arange(maps.x_values.size)
    y = maps.y_values if numeric else np.arange(maps.y_values.size)
    for row, piece in enumerate(maps.slices):
        ax = axes[row][0]
        cells = ax.pcolormesh(x_edges, y_edges, piece.mean, shading="flat", rasterized=True,
                              cmap="RdBu_r" if symmetric else "viridis",
                              vmin=-limit if symmetric else low, vmax=limit if symmetric else high)
        fig.colorbar(cells, ax=ax, label=LABELS.get(maps.value, maps.value))
        _boundaries(ax, x, y, piece.still, piece.flying)
        _axes(ax, maps, piece.label or "all points", numeric)
        if bands is not None:
            ax = axes[row][columns - 1]
            width = ax.pcolormesh(x_edges, y_edges, bands.width[row] * 1e3, shading="flat", cmap="cividis",
                                  rasterized=True)
            fig.colorbar(width, ax=ax, label="95 % band width [mm/s]")
            _boundaries(ax, x, y, piece.still, piece.flying)
            _axes(ax, maps, f"{piece.label or 'all points'}: band of the calibration ({', '.join(bands.names)}; "
                            f"{bands.samples} sets)", numeric)
        if maps.parts > 1:
            spread = axes[row][1].pcolormesh(x_edges, y_edges, piece.spread, shading="flat", cmap="magma",
                                             rasterized=True)
            fig.colorbar(spread, ax=axes[row][1], label=f"spread (std over parts) of {maps.value}")
            _boundaries(axes[row][1], x, y, piece.still, piece.flying)
            _axes(axes[row][1], maps, f"{piece.label or 'all points'}: spread over {maps.parts} parts", numeric)
    return fig


def _boundaries(ax: Any, x: np.ndarray, y: np.ndarray, still: np.ndarray, flying: np.ndarray) -> None:
    """The no-motion and flight boundaries as contours at one half (where a cell is present)."""
    if x.size < 2 or y.size < 2:
        return
    still = np.where(np.isnan(still), 0.0, still)
    flying = np.where(np.isnan(flying), 0.0, flying)
    if still.max() >= 0.5 > still.min():
        ax.contourf(x, y, still, levels=[0.5, 1.01], colors="none", hatches=["//"])
        ax.contour(x, y, still, levels=[0.5], colors="red", linewidths=1.4)
        ax.plot([], [], color="red", label="no motion (U = 0)")
    if flying.max() >= 0.5 > flying.min():
        ax.contour(x, y, flying, levels=[0.5], colors="black", linewidths=1.4, linestyles="--")
        ax.plot([], [], color="black", linestyle="--", label="flight boundary")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=7, framealpha=0.8)


def _axes(ax: Any, maps: SweepMaps, title: str, numeric: bool) -> None:
    ax.set_xlabel(LABELS.get(maps.x, maps.x))
    ax.set_ylabel(LABELS.get(maps.y, maps.y))
    ax.set_title(title, fontsize=9)
    if not numeric:
        ax.set_xticks(np.arange(maps.x_values.size), [str(v) for v in maps.x_values])
        ax.set_yticks(np.arange(maps.y_values.size), [str(v) for v in maps.y_values])


__all__ = ["sweep_figure"]
