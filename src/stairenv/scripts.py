"""Deprecated: the old name of :mod:`stairenv.screenplays` (SIMS short scripts, their database,
text embeddings, story assembly and room retrieval), kept for one release.

``stairenv.scripts`` re-exports the package's names, and its submodules are the new package's
(``import stairenv.scripts.database`` gives ``stairenv.screenplays.database``), so old imports keep
working with a ``DeprecationWarning``. The package was renamed so that "scripts" means only the
runnable ones in ``baselines/``.
"""

from __future__ import annotations

import sys
import warnings

from stairenv import screenplays
from stairenv.screenplays import *  # noqa: F403
from stairenv.screenplays import __all__  # noqa: F401
from stairenv.screenplays import database, embeddings, retrieval, schema, story

warnings.warn("stairenv.scripts is deprecated: use stairenv.screenplays (the same package, renamed so that "
              "'scripts' means only the runnable ones in baselines/)", DeprecationWarning, stacklevel=2)

# ``import stairenv.scripts.database`` and the like: Python finds the submodule here once the parent is imported
for _module in (database, embeddings, retrieval, schema, story):
    sys.modules[f"{__name__}.{_module.__name__.rpartition('.')[2]}"] = _module
del _module
