"""Plots of a transient run (``output.plots``): phase, gap, psd and forces (paper fig. 3).

Each function takes a :class:`~nsfem.result.Result`, the
:class:`~nsfem.integrate.ContactSystem` it was computed on (``run_scene`` returns both) and
a path, writes one PNG atomically (temporary file in the same directory, then a rename,
see :func:`nsfem.plot.common.save`) and returns the path:

- :func:`phase_plot`: phase portraits of the modes that vibrate most at steady state, in um and mm/s at each
  mode's largest point,
- :func:`gap_plot`: per contact part, a delamination's middle gap, a crack's opening, a ring's clearance, a
  stop's gap over time, with the counts of :mod:`nsfem.contact.tally`,
- :func:`psd_plot`: Welch PSD of the transverse displacement in an undamaged region,
- :func:`forces_plot`: each part's resultant contact force (a ring's with its angle) and impulses,
- :func:`write_plots`: the plots named in ``output.plots`` (``campbell`` is drawn by
  :func:`nsfem.plot.campbell_plot`), skipping those without data.

A plot that has nothing to show (no contacts, no contact ever loaded, no model to locate a
point on) raises :class:`NoPlotData`; :func:`write_plots` turns that into a warning.

>>> from nsfem import load_scene
>>> from nsfem.simulate import run_scene
>>> result, system = run_scene(load_scene(None, ["mesh.elements=20", "simulation.t_end=0.02"]))
>>> [m["x"] for m in delamination_middles(system)]
[0.5]
"""

from __future__ import annotations

import warnings
from pathlib import Path

from ..errors import NsfemError
from .data import (FIGSIZE, NoPlotData, closed_intervals, delamination_middles, hermite_refine,  # noqa: F401
                   loaded_contacts, measurement_point, modal_basis, modal_coordinates, welch_psd, _force_series)
from .forces import forces_plot
from .gap import gap_plot
from .phase import phase_plot
from .psd import psd_plot

#: plots this module draws, in the order of ``output.plots``
__all__ = ["FIGSIZE", "NoPlotData", "closed_intervals", "delamination_middles", "hermite_refine", "loaded_contacts",
           "measurement_point", "modal_basis", "modal_coordinates", "welch_psd", "_force_series", "forces_plot", "gap_plot",
           "phase_plot", "psd_plot", "write_plots", "RESULT_PLOTS", "PLOT_FUNCTIONS", "CONTACT_PLOTS"]
RESULT_PLOTS = ("phase", "gap", "psd", "forces")
PLOT_FUNCTIONS = {"phase": phase_plot, "gap": gap_plot, "psd": psd_plot, "forces": forces_plot}

#: the plots of contacts: left out without a word for a scene without contacts that did not list them
CONTACT_PLOTS = ("gap", "forces")


def write_plots(result, system, out_dir, names=RESULT_PLOTS, warn=None, listed: bool = True) -> list[Path]:
    """Write ``<out_dir>/<name>.png`` for each name in ``names`` (``output.plots``) and return
    the paths written. ``campbell`` is ignored here (it needs a speed sweep, see
    ``nsfem campbell``); a plot without data is skipped and its reason passed to
    ``warn(text)`` (default: :func:`warnings.warn`), except the :data:`CONTACT_PLOTS` of a run
    without contacts when ``names`` is the default list (``listed`` False: the scene named no plots);
    an unknown name raises NsfemError."""
    unknown = [n for n in names if n not in PLOT_FUNCTIONS and n != "campbell"]
    if unknown:
        raise NsfemError(f"output.plots: unknown plot(s) {', '.join(map(repr, unknown))} "
                         f"(known: {', '.join(RESULT_PLOTS)}, campbell)")
    out_dir = Path(out_dir)
    if not listed and result.gap.shape[0] == 0:
        names = [n for n in names if n not in CONTACT_PLOTS]
    written = []
    for name in dict.fromkeys(names):
        if name == "campbell":
            continue
        try:
            written.append(PLOT_FUNCTIONS[name](result, system, out_dir / f"{name}.png"))
        except NoPlotData as exc:
            msg = f"plot {name!r} skipped: {exc}"
            if warn is None:
                warnings.warn(msg, stacklevel=2)
            else:
                warn(msg)
    return written
