"""Keyword names that changed: still accepted, with a DeprecationWarning naming the new one.

"band" once named four different things (the map's margin, the trajectories'
margin, the distance grid's exact shell, the memory model's margin); each now
has its own name. Callers written against the old names keep working.
"""

from __future__ import annotations

import warnings

__all__ = ["take_renamed"]


def take_renamed(options, renames, where):
    """Move old keyword names in ``options`` (a dict, changed in place) to their new names.

    ``renames`` maps old -> new; ``where`` names the function for the warning.
    Passing both names is an error.
    """
    for old, new in renames.items():
        if old not in options:
            continue
        if new in options:
            raise ValueError(f"{where}: pass {new!r} only ({old!r} is its old name).")
        warnings.warn(f"{where}: {old!r} is now called {new!r}.", DeprecationWarning,
                      stacklevel=3)
        options[new] = options.pop(old)
    return options
