"""Parts for circuits and machines, each an ordinary :class:`~diracvi.LagrangeDiracSystem`.

from diracvi.components import Circuit, Resistor, Capacitor, VoltageSource, Sine
c = Circuit("rc")
c.add(VoltageSource(Sine(0, 1, 50), name="V1"), p="in", n="0")
c.add(Resistor(1e3, name="R1"), p="in", n="out")
c.add(Capacitor(1e-6, name="C1"), p="out", n="0")
built = c.build()   # built.system, built.q0, built.p0
"""

from typing import TYPE_CHECKING

from ..runtime.lazy import lazy_names

# (a function named as its module: imported now, or a later ``import
# diracvi.components.rotorcraft`` would bind the module to the package's name)
from .rotorcraft import MotorPropeller, rotorcraft

#: public name -> its module, imported at the first use of the name: a netlist run imports
#: the electrical parts it builds, not the rigid bodies, URDF robots or MOSFET models
_PUBLIC = {
    "ChargePortPart": "_charge_port",
    "Part": "_part",
    "BehaviouralSource": "behavioural",
    "BJT": "bjt",
    "CCCS": "controlled",
    "CCVS": "controlled",
    "VCCS": "controlled",
    "VCVS": "controlled",
    "SPICE_PARAMETERS": "diode",
    "Diode": "diode",
    "spice_diode": "diode",
    "Capacitor": "electrical",
    "CoupledInductors": "electrical",
    "CurrentSource": "electrical",
    "Ground": "electrical",
    "IdealTransformer": "electrical",
    "Inductor": "electrical",
    "MutualInductance": "electrical",
    "Resistor": "electrical",
    "VoltageSource": "electrical",
    "EMF": "electromechanical",
    "VoiceCoil": "electromechanical",
    "JFET": "jfet",
    "CoreLaw": "magnetic",
    "PiecewiseLinearCore": "magnetic",
    "Reluctance": "magnetic",
    "WoundCore": "magnetic",
    "Damper": "mechanical",
    "Fixed": "mechanical",
    "ForceSource": "mechanical",
    "Inertia": "mechanical",
    "Mass": "mechanical",
    "Pendulum": "mechanical",
    "RotationalDamper": "mechanical",
    "Spring": "mechanical",
    "TorqueSource": "mechanical",
    "TorsionSpring": "mechanical",
    "Memristor": "memristor",
    "MOSFET": "mosfet",
    "MOSFET2": "mosfet2",
    "MOSFET3": "mosfet3",
    "MOSFET6": "mosfet6",
    "BSIM3": "bsim3",
    "BSIM4": "bsim4",
    "Multibody": "multibody",
    "MultibodyModel": "multibody",
    "Assembly": "network",
    "Circuit": "network",
    "RigidBody": "rigid_body",
    "CurrentSwitch": "switch",
    "Relay": "switch",
    "VoltageSwitch": "switch",
    "parse_urdf": "urdf",
    "read_urdf": "urdf",
    "Incident": "tline",
    "TransmissionLine": "tline",
    "VDMOS": "vdmos",
    "GateDrainCapacitance": "vdmos",
    "AM": "waveforms",
    "DC": "waveforms",
    "PWL": "waveforms",
    "Exp": "waveforms",
    "Pulse": "waveforms",
    "SFFM": "waveforms",
    "Sine": "waveforms",
    "Waveform": "waveforms",
}

if TYPE_CHECKING:  # the same names as type checkers and the API docs (griffe) read them
    from ._charge_port import ChargePortPart
    from ._part import Part
    from .behavioural import BehaviouralSource
    from .bjt import BJT
    from .bsim3 import BSIM3
    from .bsim4 import BSIM4
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
    from .memristor import Memristor
    from .mosfet import MOSFET
    from .mosfet2 import MOSFET2
    from .mosfet3 import MOSFET3
    from .mosfet6 import MOSFET6
    from .multibody import Multibody, MultibodyModel
    from .network import Assembly, Circuit
    from .rigid_body import RigidBody
    from .switch import CurrentSwitch, Relay, VoltageSwitch
    from .tline import Incident, TransmissionLine
    from .urdf import parse_urdf, read_urdf
    from .vdmos import VDMOS, GateDrainCapacitance
    from .waveforms import AM, DC, PWL, SFFM, Exp, Pulse, Sine, Waveform


__getattr__, __dir__ = lazy_names(__name__, _PUBLIC, globals())

__all__ = [
    "AM",
    "BJT",
    "BSIM3",
    "BSIM4",
    "CCCS",
    "CCVS",
    "DC",
    "EMF",
    "JFET",
    "MOSFET",
    "MOSFET2",
    "MOSFET3",
    "MOSFET6",
    "PWL",
    "SFFM",
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
    "Incident",
    "Inductor",
    "Inertia",
    "Mass",
    "Memristor",
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
    "TransmissionLine",
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
