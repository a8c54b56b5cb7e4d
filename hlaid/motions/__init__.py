"""Ground motions: the record dataclass and the records shipped with hlaid (read files with
:func:`hlaid.io.read`)."""

from .builtin import SUITE, builtin_records, builtin_suite, load_builtin
from .record import GroundMotion

__all__ = ["GroundMotion", "builtin_records", "builtin_suite", "load_builtin", "SUITE"]
