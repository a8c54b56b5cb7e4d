"""Ground motions: the record dataclass, file readers and built-in records."""

from .builtin import SUITE, builtin_records, builtin_suite, load_builtin
from .readers import READERS, read_at2, read_csv, read_motion, read_text
from .record import GroundMotion

__all__ = ["GroundMotion", "read_motion", "read_at2", "read_text", "read_csv", "READERS",
           "builtin_records", "builtin_suite", "load_builtin", "SUITE"]
