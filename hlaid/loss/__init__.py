"""Losses of a clone: FEMA P-58 through pelicun (the optional extra ``hlaid[loss]``).

:func:`clone_demands` runs the clone (and its ensemble) under records, as recorded or at an IDA
stripe, and returns the demands (PID, PFA, RID from the replay itself, the intensity) per
realization, written in pelicun's demand format by :meth:`Demands.write_csv`;
:func:`assess_losses` runs pelicun's FEMA P-58 assessment of the recorded event and of the
stripes with a default inventory per structural system (:data:`INVENTORIES`) or the user's
(:func:`hlaid.run.loss_of_run` does it for a run folder, ``hlaid loss RUN_DIR``). Method, sources and a
worked example: ``docs/loss.md``. Only :mod:`.fema_p58` imports pelicun, when it runs.
"""

from .assess import ASSUMPTIONS, LossResult, assess_demands, assess_losses, loss_of_demand_file
from .config import LossConfig
from .demands import DemandFile, Demands, clone_demands, read_demand_csv
from .inventory import INVENTORIES, Inventory, default_inventory, get_inventory, read_inventory

__all__ = ["ASSUMPTIONS", "DemandFile", "Demands", "LossConfig", "LossResult", "INVENTORIES", "Inventory",
           "assess_demands", "assess_losses", "clone_demands", "default_inventory", "get_inventory",
           "loss_of_demand_file", "read_demand_csv", "read_inventory"]
