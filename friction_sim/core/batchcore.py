"""The vectorized engine of :mod:`friction_sim.core.batch` (placeholder: the scalar loop)."""

from __future__ import annotations

from friction_sim.core import batch


def run_numpy(pop: batch.Population, settle: int, count: int, times: batch.Floats | None, *,
              shortcut: bool = True) -> batch.BatchResult:
    """All sliders together (for now: the exact scalar loop)."""
    del shortcut
    return batch._run_scalar(pop, settle, count, times)  # noqa: SLF001 - placeholder until the numpy engine lands
