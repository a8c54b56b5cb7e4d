"""Real-structure validation: identify a clone from one recorded event, predict the others.

``docs/validation.md`` reads the results; ``scripts/validate_real.py`` runs a study and draws
its figures. For every structure of a :class:`ValidationConfig` and every identification event:

1. read the event (a reader of :data:`hlaid.io.MEASUREMENT_READERS`); no masses are given,
   so HLA and the clone are mass-normalised with the structure's ``mass_ratios``;
2. identify a clone with :func:`hlaid.identify_clone` (HLA, regressions, SVMs, replay
   refinement). When no story yielded (:class:`~hlaid.errors.NotIdentifiableError`) a
   nonlinear clone cannot be identified, and the protocol falls back, *labelled as such*, to
   a linear clone (``alpha = 1``): HLA's k0, fitted to the measured accelerations as the
   structure's ``fallback_fit`` says (:func:`linear_clone`);
3. save the clone JSON, load it back (:meth:`hlaid.clone.Clone.load`), and replay it under the
   ground motion of every prediction event (and of its own event, the self-replay);
4. compare per floor the predicted and measured displacement relative to the ground (measured
   displacements when the data hold them, else integrated accelerations; both band-passed
   alike): correlation ``R``, peak inter-story drift error, and the clone's elastic
   stiffness ke(t) against HLA's ke of that event (mean relative error over half cycles, the
   paper's 2.1 % metric).

Every number is in the package units, per unit of the (relative) masses when mass-normalised.

Modules: :mod:`.schema` (the config), :mod:`.clones` (identification and the linear
fallback), :mod:`.predict` (:func:`hlaid.predict_event` labelled by the study), :mod:`.protocol` (the run),
:mod:`.tables` (Markdown), :mod:`.linear_peer` (a linear state-space peer from the optional
``mdof``, on the same events and metric; ``scripts/study_linear_peer.py``).
"""

from .clones import FALLBACK_FITS, IdentifiedClone, identify_event, linear_clone
from .linear_peer import LinearPeer, PeerCase, PeerPrediction, PeerSettings, compare_peer, peer_cases, peer_grid
from .predict import StudyPrediction, study_prediction
from .protocol import ValidationResult, run_validation
from .schema import (
    EventSpec,
    PaperTargets,
    StructureSpec,
    ValidationConfig,
    identify_config_of,
    load_validation_config,
    read_event,
)
from .tables import format_tables

__all__ = ["EventSpec", "StructureSpec", "PaperTargets", "ValidationConfig", "load_validation_config",
           "identify_config_of", "read_event", "FALLBACK_FITS", "IdentifiedClone", "linear_clone", "identify_event",
           "StudyPrediction", "study_prediction", "ValidationResult", "run_validation", "format_tables",
           "LinearPeer", "PeerSettings", "PeerPrediction", "PeerCase", "compare_peer", "peer_cases", "peer_grid"]
