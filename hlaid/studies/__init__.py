"""Studies built on the library: they measure it, they are not part of it.

* :mod:`hlaid.studies.compare`: every identifier on the same simulated cases (parameter
  errors, replay correlation, time, failures); ``scripts/compare_identifiers.py``.
* :mod:`hlaid.studies.validation`: real-structure validation, a clone identified from one
  recorded event predicting the others; ``scripts/validate_real.py``.
* :mod:`hlaid.studies.hla_accuracy`: HLA against the truth of simulated measurements;
  ``scripts/study_hla_accuracy.py``.
* :mod:`hlaid.studies.bootstrap`: the parametric bootstrap that checks a clone's uncertainty;
  ``scripts/study_uncertainty.py``.

Nothing here is imported by ``hlaid`` itself; import the study module you need.
"""
