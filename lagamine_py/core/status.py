"""Contact status codes, as contact laws return them and writers name them.

``OPEN``, ``STICK`` and ``SLIP`` are what a contact law returns for a point.  ``NONE`` is never
returned by a law: the contact element gives it, in its outputs, to a point whose normal
misses every foundation (the point cannot touch anything in that configuration).
"""
from __future__ import annotations

__all__ = ["OPEN", "STICK", "SLIP", "NONE", "STATUS_NAMES"]

OPEN, STICK, SLIP, NONE = 0, 1, 2, 3
#: the name of each code, as written in contact.csv and named in the VTU field data
STATUS_NAMES = ("open", "stick", "slip", "none")
