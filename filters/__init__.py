"""Built-in filters of meshopt-toolkit, installed as ``meshopt_toolkit.filters``.

One module per filter. This folder lives at the top level of the repository and is
mapped onto ``meshopt_toolkit.filters`` by setuptools ``package-dir``; importing it under
the bare name ``filters`` would give a second, unregistered copy, so that is refused.
"""

if __name__ != "meshopt_toolkit.filters":  # pragma: no cover - guarded by a test
    raise ImportError(
        "the filters folder is part of meshopt_toolkit: import meshopt_toolkit.filters, "
        "not 'filters'"
    )
