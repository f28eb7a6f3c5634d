"""A variable-step run's NetCDF file written with h5netcdf alone.

The file holds one variable per saved vector over the coordinate ``time`` and the run's
settings as attributes: the layout ``Result.to_xarray().to_netcdf(engine="h5netcdf")``
writes (float variables with ``_FillValue`` NaN, attributes as NetCDF stores them), so
``xarray.open_dataset`` reads the same dataset from either. It is written here without
building that dataset because importing xarray (and pandas under it) costs about a
second, more than the whole run of a small circuit whose program is in the cache.
"""

from __future__ import annotations

import numpy as np


def write(path, time: np.ndarray, variables: dict[str, np.ndarray], attrs: dict) -> None:
    """Write ``variables`` (name → values over ``time``) and the global ``attrs`` to a
    new NetCDF-4 file at ``path``."""
    import h5netcdf

    with h5netcdf.File(path, "w") as f:
        f.dimensions = {"time": len(time)}
        for name, values in {"time": time, **variables}.items():
            values = np.asarray(values, dtype=np.float64)
            var = f.create_variable(name, ("time",), np.float64, fillvalue=np.nan)
            var[...] = values
        for key, value in attrs.items():
            # NetCDF keeps a number as a one-element array (as xarray writes it)
            f.attrs[key] = value if isinstance(value, str) else np.atleast_1d(value)
