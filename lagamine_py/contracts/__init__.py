"""The contract of every plugin kind as checks: plain functions returning findings.

One suite per kind, run on a plugin *class* (built-in or third-party alike)::

    findings = check_plugin("laws", MyLaw)       # [Finding(check, passed, detail, skipped)]

The project's tests run them over every registered plugin (``tests/test_contracts.py``) and
``lagamine-py plugins --check [NAME ...]`` runs them on what is installed.  No pytest here: a
check returns a :class:`Finding` whose ``detail`` gives the numbers it compared.

Every number compared comes from an independent source: central finite differences, exact
invariants (partition of unity, areas of affine maps, rigid motions, patch tests), closed forms
(Hooke's law), or the file system itself (what reached the disk).  One module per kind
(:mod:`.elements`, :mod:`.material_laws`, :mod:`.contact_laws`, :mod:`.writers`,
:mod:`.solvers`, :mod:`.checks`), :mod:`.findings` for what they share; what each suite checks:

* elements (:func:`check_element`): shape functions (partition of unity, Kronecker property,
  linear fields), their derivatives against central differences, the Gauss rule (area and first
  moments of an affine element), the faces (each an edge of the element, running with the
  element on its left, node order of :func:`~lagamine_py.elements.shapes.line_shape`), the
  outline, the Jacobian check (:meth:`~lagamine_py.elements.base.Element.invalid`), the recovery
  of Gauss values at the nodes, the VTK cell's node order, the patch test, rigid motions and
  the tangent against central differences of the internal force (small strain and NLGEOM,
  elastic and elasto-plastic).  Only the :class:`~lagamine_py.elements.base.Element` contract is
  used: any topology declared through it is checked.
* material laws (:func:`check_material_law`): construction from
  :meth:`~lagamine_py.core.plugin.Parametrized.example_values`, ``init_state``, the elastic
  moduli, material-point paths driven with the law's tangent into plastic states, the tangent
  against central differences there, objectivity (``isotropic`` laws), the committed state left
  unchanged, batched shapes equal to point-by-point results.
* contact laws (:func:`check_contact_law`): construction, state keys and status codes, every
  tangent entry against central differences in open, closing, stick, slip and separating
  sub-intervals, the entries chained over sub-intervals
  (:func:`~lagamine_py.laws.contact_point.drive`), the committed state left unchanged,
  ``inadmissible()`` empty along the law's own path, the frozen holds.
* writers (:func:`check_writer`): a real run's hook calls recorded once and replayed into the
  writer in the contract's order, with ``open`` tracked: no exception, nothing left unflushed
  after any hook, the bytes on disk, nothing written outside the output directory.
* linear solvers (:func:`check_solver`): non-symmetric and symmetric systems to round-off, a new
  factorisation with the structure kept, singular matrices reported with the right DOFs.
* checks (:func:`check_check`): an empty directory is reported (NaN and a message), a finished
  run gives the contract's keys.
"""
from __future__ import annotations

from typing import Callable

from .checks import CHECK_ITEMS, check_check
from .contact_laws import CONTACT_ITEMS, check_contact_law
from .elements import ELEMENT_ITEMS, check_element
from .findings import ContractFailure, Finding, Report
from .material_laws import LAW_ITEMS, check_material_law
from .solvers import SOLVER_ITEMS, check_solver
from .writers import SAMPLE_DECK, WRITER_ITEMS, check_writer, sample_run

__all__ = ["Finding", "Report", "ContractFailure", "SUITES", "ITEMS", "check_plugin",
           "check_registered", "check_element", "check_material_law", "check_contact_law",
           "check_writer", "check_solver", "check_check", "sample_run", "SAMPLE_DECK"]

SUITES: dict[str, Callable[[type], list[Finding]]] = {
    "elements": check_element, "laws": check_material_law, "contact_laws": check_contact_law,
    "writers": check_writer, "solvers": check_solver, "checks": check_check}

#: the checks of each kind, in the order they run
ITEMS = {"elements": ELEMENT_ITEMS, "laws": LAW_ITEMS, "contact_laws": CONTACT_ITEMS,
         "writers": WRITER_ITEMS, "solvers": SOLVER_ITEMS, "checks": CHECK_ITEMS}


def check_plugin(kind: str, cls: type) -> list[Finding]:
    """The findings of the contract suite of plugin kind ``kind`` on class ``cls``."""
    return SUITES[kind](cls)


def check_registered(names: list[str] | None = None,
                     progress: Callable[[Report], None] | None = None) -> list[Report]:
    """Run the suites on the registered plugins (aliases once), all of them or those named
    ``names`` (case-insensitive, in every kind that has the name; KeyError for a name no kind
    has).  ``progress`` is called with each report as it is done."""
    from ..core.params import did_you_mean
    from ..registry import KINDS, REGISTRY
    wanted = None
    if names:
        asked = {str(n).upper() for n in names}
        wanted = {(k, REGISTRY.canonical(k, n)) for k in KINDS for n in asked
                  if n in REGISTRY.names(k)}
        unknown = sorted(n for n in asked if not any(n in REGISTRY.names(k) for k in KINDS))
        if unknown:
            known = {n for k in KINDS for n in REGISTRY.names(k)}
            raise KeyError(f"no registered plugin {', '.join(unknown)}"
                           f"{did_you_mean(unknown[0], known)}")
    reports = []
    for kind in KINDS:
        for entry in REGISTRY.entries(kind):
            if wanted is not None and (kind, entry.name) not in wanted:
                continue
            rep = Report(kind, entry.name, entry.origin, check_plugin(kind, entry.cls))
            reports.append(rep)
            if progress is not None:
                progress(rep)
    return reports
