"""Contact status codes, as contact laws return them and writers name them."""
from __future__ import annotations

__all__ = ["OPEN", "STICK", "SLIP", "STATUS_NAMES"]

OPEN, STICK, SLIP = 0, 1, 2
#: the name of each code, as written in contact.csv
STATUS_NAMES = ("open", "stick", "slip")
