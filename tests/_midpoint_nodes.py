"""A midpoint trajectory read at its interior nodes ``t_k``, as the discrete power
balances of the circuit tests state it: node currents ``ī = (Δq_{k−1} + Δq_k)/2h``, step
voltages ``Δw/h``, and step values averaged onto the nodes."""

import numpy as np


class MidpointNodes:
    def __init__(self, traj):
        self.traj = traj
        self.h = float(traj.dt)

    def coord(self, name):
        return self.traj.q[:, self.traj.coords.index(name)]

    def node_current(self, name):
        dq = np.diff(self.coord(name))
        return (dq[:-1] + dq[1:]) / (2 * self.h)

    def step_volts(self, name):
        return np.diff(self.coord(name)) / self.h

    @staticmethod
    def at_nodes(x):
        """The two steps' values around each interior node, averaged."""
        return (x[:-1] + x[1:]) / 2
