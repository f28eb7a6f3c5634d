"""Parameter sweeps (``dv.sweep``): many parameter values of one model in one batched run.

Named ``sweeps`` (not ``sweep``) so that the package never shadows the ``diracvi.sweep``
function: importing a submodule ``diracvi.sweep.x`` would rebind that attribute."""
