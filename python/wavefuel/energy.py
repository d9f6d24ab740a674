"""Vehicle classes and their energy models (docs/energy.md) over numpy arrays, through the library's array kernel:
the same bits as `wavefuel energy`."""
import ctypes as C

import numpy as np

from . import _lib
from ._lib import WfError, WfVehicleClass, check, lib, text


class VehicleClass:
    """One class file loaded by the library (found by name on the class search path, or a path to a .yaml file).
    Attributes: name, label, path, duty, fuel_type, model; `keys` the class file's numeric keys and `params` its energy
    model's parameters, each {key: (value, unit)}."""

    def __init__(self, name_or_path):
        self._vc = WfVehicleClass()
        err = WfError()
        check(lib.wf_vehicle_find(str(name_or_path).encode(), C.byref(self._vc), C.byref(err)), err)
        self._init_fields()

    @classmethod
    def _adopt(cls, vc):
        """Take over a loaded WfVehicleClass (its params are then freed by this object)."""
        self = cls.__new__(cls)
        self._vc = WfVehicleClass()
        C.memmove(C.byref(self._vc), C.byref(vc), C.sizeof(WfVehicleClass))
        self._init_fields()
        return self

    def _init_fields(self):
        vc, m = self._vc, self._vc.model.contents
        self.name, self.label, self.path = text(vc.name), text(vc.label), text(vc.path)
        self.duty, self.fuel_type = text(lib.wf_duty_name(vc.duty)), text(lib.wf_fuel_name(vc.fuel))
        self.model = text(m.name)
        self.project_default = bool(m.project_default)
        self.params = {text(s.key): (C.c_double.from_address(vc.params + s.offset).value, text(s.unit))
                       for s in m.spec[:m.n_spec]}
        base = C.addressof(vc)
        self.keys = {text(s.key): (C.c_double.from_address(base + s.offset).value, text(s.unit))
                     for s in _lib.table("wf_vehicle_keys", _lib.WfParamSpec, "wf_vehicle_n_keys")}

    def __del__(self):
        vc = getattr(self, "_vc", None)
        if vc is not None and vc.params:
            lib.wf_vehicle_free(C.byref(vc))

    def __repr__(self):
        return f"<wavefuel.VehicleClass {self.name} ({self.duty}, {self.fuel_type}, {self.model}) from {self.path}>"

    def evaluate(self, v, a, theta=0.0, project=False):
        """Fuel rate (g/s), equivalent power (kW) and feasibility flag (0 feasible, 1 acceleration above a_max,
        2 negative speed) at speed v (m/s), acceleration a (m/s^2) and grade theta (rad), broadcast together.
        project: clip a to a_max(v, theta) first."""
        v, a, th = (np.ascontiguousarray(x, dtype=np.float64) for x in np.broadcast_arrays(v, a, theta))
        fuel = np.empty(v.shape)
        flag = np.empty(v.shape, dtype=np.uint8)
        ptr = lambda x: x.ctypes.data_as(C.c_void_p)
        self._vc.model.contents.eval(self._vc.params, v.size, ptr(v), ptr(a), ptr(th), int(bool(project)),
                                     ptr(fuel), ptr(flag))
        return fuel, fuel * self._vc.kw_per_gps, flag

    def fuel(self, v, a, theta=0.0, project=False):
        """Fuel rate in g/s (see evaluate)."""
        return self.evaluate(v, a, theta, project)[0]

    def a_max(self, v, theta=0.0):
        """Largest feasible acceleration (m/s^2) at speed v (m/s) and grade theta (rad), broadcast together."""
        v, th = np.broadcast_arrays(np.asarray(v, dtype=np.float64), np.asarray(theta, dtype=np.float64))
        f, p = self._vc.model.contents.a_max, self._vc.params
        out = np.fromiter((f(p, float(x), float(t)) for x, t in zip(v.ravel(), th.ravel())), np.float64, v.size)
        return out.reshape(v.shape) if v.ndim else float(out[0])


_cache = {}


def vehicle_class(cls):
    """A VehicleClass by name or path (kept for the process: classes are read once), or cls itself."""
    if isinstance(cls, VehicleClass):
        return cls
    if cls not in _cache:
        _cache[cls] = VehicleClass(cls)
    return _cache[cls]


def fuel(cls, v, a, theta=0.0, project=False):
    """Fuel rate (g/s) of class `cls` (name, path or VehicleClass) at speed v (m/s), acceleration a (m/s^2) and
    grade theta (rad), numpy arrays broadcast together; project clips a to a_max first (`wavefuel energy
    --project`)."""
    return vehicle_class(cls).fuel(v, a, theta, project)


def a_max(cls, v, theta=0.0):
    """Largest feasible acceleration (m/s^2) of class `cls` at speed v (m/s) and grade theta (rad)."""
    return vehicle_class(cls).a_max(v, theta)


def classes():
    """Every class on the class search path (sorted by name), as VehicleClass objects."""
    arr = C.POINTER(WfVehicleClass)()
    n = C.c_size_t()
    err = WfError()
    check(lib.wf_vehicle_list(C.byref(arr), C.byref(n), C.byref(err)), err)
    try:
        return [VehicleClass._adopt(arr[i]) for i in range(n.value)]
    finally:
        _lib.libc.free(C.cast(arr, C.c_void_p))


def class_names():
    """Names of the classes on the search path."""
    return [c.name for c in classes()]
