"""pandas, imported only when a ``to_dataframe()`` view is asked for (the ``[pandas]`` extra)."""


def require_pandas():
    """The ``pandas`` module, or an ``ImportError`` that says how to install it."""
    try:
        import pandas
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise ImportError(
            "to_dataframe() needs pandas, an optional dependency: "
            "pip install 'diffguide[pandas]' (or pip install pandas)"
        ) from exc
    return pandas
