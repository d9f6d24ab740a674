"""Many Simulations stepped as one batch in C (the library's wf_sims_*, include/wavefuel/engine.h): the runs' steps in
parallel over runs on OpenMP threads, each run single-threaded inside and giving the bits it gives alone; one
external group's observations and commands of every run as one array, and every vehicle's speed."""
import ctypes as C

import numpy as np

from . import _lib
from ._lib import WfError, check, lib

_vp, _err = C.c_void_p, C.POINTER(WfError)
_sp, _dp = C.POINTER(C.c_size_t), C.POINTER(C.c_double)
_SIGNATURES = {
    "wf_sims_step": (C.c_int, [_vp, C.c_size_t, C.c_long, C.c_int, _vp]),
    "wf_sims_observe": (C.c_int, [_vp, C.c_size_t, _vp, _vp, C.c_size_t, _err]),
    "wf_sims_set_actions": (C.c_int, [_vp, C.c_size_t, _vp, _vp, C.c_size_t, _err]),
    "wf_sims_speeds": (C.c_int, [_vp, C.c_size_t, _vp, C.c_size_t, _err]),
}
for _name, (_res, _args) in _SIGNATURES.items():
    getattr(lib, _name).restype, getattr(lib, _name).argtypes = _res, _args


class Batch:
    """The runs `sims` (begun Simulations, held by the caller; rebuild the Batch when one is replaced) with
    `groups[k]` the external group of run k (a name or an index). Buffers are allocated here once: observe() and
    speeds() return arrays that the next call overwrites (copy to keep them)."""

    def __init__(self, sims, groups):
        self.sims = list(sims)
        for s in self.sims:
            s._alive()
            s._begin()
        n = len(self.sims)
        self._ptrs = (C.c_void_p * n)(*[s._ptr.value for s in self.sims])
        self._groups = np.array([s.group_index(g) for s, g in zip(self.sims, groups)], dtype=np.uintp)
        self._errs = (WfError * n)()
        self._err = WfError()
        self.n_rows = int(sum(lib.wf_sim_group_size(s._ptr, int(g)) for s, g in zip(self.sims, self._groups)))
        self.n_vehicles = int(sum(s.n_vehicles for s in self.sims))
        self._obs = np.empty((self.n_rows, 3))
        self._v = np.empty(self.n_vehicles)
        self._p_ptrs = C.addressof(self._ptrs)
        self._p_groups, self._p_obs, self._p_v = (a.ctypes.data for a in (self._groups, self._obs, self._v))

    def set_actions(self, actions):
        """Commands of every run's group, runs one after the other (n_rows values), as Simulation.set_actions."""
        u = np.ascontiguousarray(actions, dtype=np.float64).ravel()
        check(lib.wf_sims_set_actions(self._p_ptrs, len(self.sims), self._p_groups, u.ctypes.data, u.size,
                                      C.byref(self._err)), self._err)

    def step(self, n, threads):
        """n steps of every run, on `threads` OpenMP threads over runs."""
        rc = lib.wf_sims_step(self._p_ptrs, len(self.sims), int(n), int(threads), C.addressof(self._errs))
        if rc:
            k = next(i for i, e in enumerate(self._errs) if e.code)
            raise _lib.WavefuelError(f"run {k} of the batch: " + self._errs[k].msg.decode(errors="replace"), rc)

    def observe(self):
        """(n_rows, 3) observations of every run's group, runs one after the other (Simulation.observe)."""
        check(lib.wf_sims_observe(self._p_ptrs, len(self.sims), self._p_groups, self._p_obs, self.n_rows,
                                  C.byref(self._err)), self._err)
        return self._obs

    def speeds(self):
        """Speeds (m/s) of every vehicle on the roads, each run in road order (a ring: vehicle i + 1 leads vehicle
        i; a corridor: the front vehicle first), runs one after the other. Raises WavefuelError when vehicles
        entered or left since the Batch was built."""
        check(lib.wf_sims_speeds(self._p_ptrs, len(self.sims), self._p_v, self.n_vehicles, C.byref(self._err)),
              self._err)
        return self._v
