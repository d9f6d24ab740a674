"""Scenarios (docs/scenarios.md, docs/corridors.md) loaded and validated by the library's loader."""
import ctypes as C
import json
import os

from . import _lib
from ._lib import WfError, check, lib, text


def _assignments(overrides):
    """{key.path: value} or ["key.path=value", ...] as the loader's --set lines (YAML values: JSON text for
    lists, maps and booleans)."""
    if overrides is None:
        return []
    if isinstance(overrides, dict):
        def value(v):
            return v if isinstance(v, str) else json.dumps(v)
        return [f"{k}={value(v)}" for k, v in overrides.items()]
    return [str(s) for s in overrides]


class Scenario:
    """A loaded scenario (the library's WfScenario, immutable). Build with Scenario.load(path, overrides) or
    Scenario.from_dict(d); a Simulation keeps its scenario alive."""

    def __init__(self, _ptr):
        self._ptr = _ptr
        sc = C.cast(_ptr, C.POINTER(_lib.WfScenario)).contents
        self.path, self.name = text(sc.path), text(sc.name)
        self.duration_s, self.dt_s, self.warmup_s = sc.duration_s, sc.dt_s, sc.warmup_s
        self.output_interval_s = sc.output_interval_s
        self.integrator, self.seed = text(sc.integrator), sc.seed
        self.n_steps = lib.wf_scenario_n_steps(_ptr)
        self.classes = [text(sc.classes[i].vc.name) for i in range(sc.n_classes)]
        self.groups = [text(sc.groups[i].name) for i in range(sc.n_groups)]
        self.output_path = text(sc.output_path)  # output.path, else output/NAME.h5
        self.kind = "corridor" if sc.corridor else "ring"

    @staticmethod
    def _load(call, args, overrides):
        sets = _assignments(overrides)
        arr = (C.c_char_p * max(len(sets), 1))(*[s.encode() for s in sets])
        ptr = C.c_void_p()
        err = WfError()
        check(call(*args, arr, len(sets), C.byref(ptr), C.byref(err)), err)
        return Scenario(ptr)

    @classmethod
    def load(cls, path, overrides=None):
        """Load a scenario file with overrides ({"fleet.vehicles": 44} or ["fleet.vehicles=44"], as --set)."""
        return cls._load(lib.wf_scenario_load, (os.fspath(path).encode(),), overrides)

    @classmethod
    def from_text(cls, text_, path="scenario.yaml", overrides=None):
        """Load YAML text; `path` names it in messages and relative paths (grade CSV, class files) resolve
        against its directory."""
        return cls._load(lib.wf_scenario_load_text, (os.fspath(path).encode(), text_.encode()), overrides)

    @classmethod
    def from_dict(cls, d, path="scenario.yaml", overrides=None):
        """Load a scenario given as a dict (the YAML file's structure): written as JSON text, which is YAML."""
        return cls.from_text(json.dumps(d, indent=1), path, overrides)

    def __del__(self):
        if getattr(self, "_ptr", None):
            lib.wf_scenario_destroy(C.byref(self._ptr))

    def __repr__(self):
        return f"<wavefuel.Scenario {self.name} from {self.path}: {self.duration_s:g} s, dt {self.dt_s:g} s>"
