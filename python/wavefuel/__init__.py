"""wavefuel from Python (docs/python.md): vehicle energy models over numpy arrays, scenarios, runs stepped from
Python with their state as numpy views, HDF5 results. A thin layer over libwavefuel.so (ctypes): the physics, the
checks and the error messages are the library's."""
from ._lib import WavefuelError, class_path, library_path, set_class_path
from . import energy
from .energy import VehicleClass
from .result import Result, read
from .scenario import Scenario
from .simulation import Quantity, Simulation
from . import envs
from . import mlp
from .mlp import Network, export_mlp, mlp_forward, read_mlp

__all__ = ["WavefuelError", "class_path", "library_path", "set_class_path", "energy", "VehicleClass", "Result",
           "read", "Scenario", "Quantity", "Simulation", "envs", "mlp", "Network", "export_mlp", "mlp_forward",
           "read_mlp"]
