"""Compatibility alias: this module now lives at :mod:`meshopt_toolkit.diagnostics`.

``import meshopt_toolkit.taylor`` returns that module itself (monkeypatching either name
patches the same object); new code imports the new path.
"""

import sys

from . import diagnostics as _module

sys.modules[__name__] = _module
