"""Numbers and units as a person reads them: one spelling for tables, summaries, titles and messages.

Datasets keep CF spellings (``um2/T*``, ``1`` for dimensionless); what is
printed or drawn shows ``µm²/T*`` and leaves dimensionless units out.
"""
from __future__ import annotations

SHOWN_UNITS = {"1": "", "um": "µm", "um2": "µm²", "um3": "µm³", "um2/T*": "µm²/T*", "um/T*": "µm/T*"}


def units_text(units: str) -> str:
    """'um2/T*' -> 'µm²/T*', '1' -> '' (dimensionless)."""
    return SHOWN_UNITS.get(str(units), str(units))
