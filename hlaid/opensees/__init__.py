"""Export a clone as a standalone OpenSeesPy script, and run its model in-process.

:func:`export_opensees` writes a runnable Python file that builds the clone in OpenSees
(``zeroLength`` elements with ``uniaxialMaterial BoucWen``, floor masses, Rayleigh damping
applied with ``-doRayleigh 1``, the parameter mapping of docs/DESIGN.md section 3) and, run as a
program, analyses a record given on the command line and writes the peak drifts. The file is
:mod:`~hlaid.opensees.standalone` (the model-building and analysis code) followed by the clone's
parameters as literals (:mod:`~hlaid.opensees.script`); :func:`run_opensees` calls the same
``standalone.analyze`` with the same data (:mod:`~hlaid.opensees.run`).

P-Delta (a shear model has no columns to carry a P-Delta transformation): each story gets
a parallel ``zeroLength`` with ``uniaxialMaterial Elastic`` of stiffness ``-P_i/h_i``, the
same linearised geometric stiffness hlaid subtracts from the story force, with
``-doRayleigh 0`` because hlaid's damping ``C = a0 M + a1 K0`` uses K0 without it.

A collapse model (:mod:`hlaid.model.collapse`) adds its gap springs to that parallel element:
``uniaxialMaterial Parallel`` of ``Elastic`` (sum of the slope changes, minus ``P_i/h_i``) and, per
kink, two ``ElasticPPGap`` of unit stiffness yielding at ``+-x_j`` with ``damage`` (the gap grows
with the plastic deformation), with factors ``-dk_j``: exactly the gap springs of hlaid's law.

openseespy is optional (``pip install openseespy==3.5.1.12`` on Python 3.11); without it,
exporting works and running raises :class:`OpenSeesUnavailable`.
"""

from .run import OpenSeesResult, OpenSeesUnavailable, import_opensees, run_opensees, run_opensees_batch
from .script import export_opensees, model_data, opensees_script

__all__ = [
    "OpenSeesResult",
    "OpenSeesUnavailable",
    "export_opensees",
    "import_opensees",
    "model_data",
    "opensees_script",
    "run_opensees",
    "run_opensees_batch",
]
