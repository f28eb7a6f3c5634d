"""Parts for circuits and machines, each an ordinary :class:`~diracvi.LagrangeDiracSystem`.

from diracvi.components import Circuit, Resistor, Capacitor, VoltageSource, Sine
c = Circuit("rc")
c.add(VoltageSource(Sine(0, 1, 50), name="V1"), p="in", n="0")
c.add(Resistor(1e3, name="R1"), p="in", n="out")
c.add(Capacitor(1e-6, name="C1"), p="out", n="0")
built = c.build()   # built.system, built.q0, built.p0
"""

from ._charge_port import ChargePortPart
from ._part import Part
from .behavioural import BehaviouralSource
from .bjt import BJT
from .controlled import CCCS, CCVS, VCCS, VCVS
from .diode import SPICE_PARAMETERS, Diode, spice_diode
from .electrical import (
    Capacitor,
    CoupledInductors,
    CurrentSource,
    Ground,
    IdealTransformer,
    Inductor,
    MutualInductance,
    Resistor,
    VoltageSource,
)
from .electromechanical import EMF, VoiceCoil
from .jfet import JFET
from .magnetic import CoreLaw, PiecewiseLinearCore, Reluctance, WoundCore
from .mechanical import (
    Damper,
    Fixed,
    ForceSource,
    Inertia,
    Mass,
    Pendulum,
    RotationalDamper,
    Spring,
    TorqueSource,
    TorsionSpring,
)
from .mosfet import MOSFET
from .mosfet2 import MOSFET2
from .mosfet6 import MOSFET6
from .multibody import Multibody, MultibodyModel
from .network import Assembly, Circuit
from .rigid_body import RigidBody
from .rotorcraft import MotorPropeller, rotorcraft
from .switch import CurrentSwitch, Relay, VoltageSwitch
from .urdf import parse_urdf, read_urdf
from .vdmos import VDMOS, GateDrainCapacitance
from .waveforms import DC, PWL, Exp, Pulse, Sine, Waveform

__all__ = [
    "BJT",
    "CCCS",
    "CCVS",
    "DC",
    "EMF",
    "JFET",
    "MOSFET",
    "MOSFET2",
    "MOSFET6",
    "PWL",
    "SPICE_PARAMETERS",
    "VCCS",
    "VCVS",
    "VDMOS",
    "Assembly",
    "BehaviouralSource",
    "Capacitor",
    "ChargePortPart",
    "Circuit",
    "CoreLaw",
    "CoupledInductors",
    "CurrentSource",
    "CurrentSwitch",
    "Damper",
    "Diode",
    "Exp",
    "Fixed",
    "ForceSource",
    "GateDrainCapacitance",
    "Ground",
    "IdealTransformer",
    "Inductor",
    "Inertia",
    "Mass",
    "MotorPropeller",
    "Multibody",
    "MultibodyModel",
    "MutualInductance",
    "Part",
    "Pendulum",
    "PiecewiseLinearCore",
    "Pulse",
    "Relay",
    "Reluctance",
    "Resistor",
    "RigidBody",
    "RotationalDamper",
    "Sine",
    "Spring",
    "TorqueSource",
    "TorsionSpring",
    "VoiceCoil",
    "VoltageSource",
    "VoltageSwitch",
    "Waveform",
    "WoundCore",
    "parse_urdf",
    "read_urdf",
    "rotorcraft",
    "spice_diode",
]
