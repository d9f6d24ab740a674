"""Many Simulations stepped as one batch of RL actions in C (include/wavefuel/rl.h): every run's external group
takes its commands from one array, the runs step in parallel over runs on OpenMP threads (each run single-threaded
inside, giving the bits it gives alone), and each run's observation, reward and its terms come back as arrays."""
import ctypes as C
import functools

import numpy as np

from . import _lib
from ._lib import WfError, check, lib

# Columns of info (rl.h: WF_RL_FUEL ...).
INFO = ("fuel", "gap", "comfort", "fuel_rate_gps", "mean_speed_mps", "t_s")


class RlBatch:
    """The runs `sims` (Simulations that have begun, held by the caller, stepped only through this batch while it
    lives; rebuild it when one is replaced) with `groups[k]` the external group of run k (a name or an index),
    `reward` a wavefuel.envs.Reward, an action lasting action_steps steps of dt_s. The vehicles on each road must
    stay the same while the batch lives. step() returns arrays that the next call overwrites (copy to keep).
    thread_check: calls between the thread governor's probes of the other thread count (None: the library's
    default, WF_RL_THREAD_CHECK in rl.h; 0: always the threads asked). bounds: (low, high), n_rows values each (or
    numbers): every command is clipped to them in C as np.minimum(np.maximum(u, low), high) would (None: none)."""

    def __init__(self, sims, groups, reward, action_steps, dt_s, thread_check=None, bounds=None):
        self.sims = list(sims)
        for s in self.sims:
            s._alive()
            s._begin()
        n = len(self.sims)
        self._ptrs = (C.c_void_p * n)(*[s._ptr.value for s in self.sims])
        self._groups = np.array([s.group_index(g) for s, g in zip(self.sims, groups)], dtype=np.uintp)
        self._rw = reward._c()
        self._b = C.c_void_p()
        err = WfError()
        check(lib.wf_rl_batch_create(self._ptrs, n, self._groups.ctypes.data, C.byref(self._rw), int(action_steps),
                                     float(action_steps * dt_s), C.byref(self._b), C.byref(err)), err)
        if thread_check is not None:
            if int(thread_check) < 0:
                self.close()
                raise ValueError(f"thread_check must be >= 0 (got {thread_check})")
            lib.wf_rl_batch_set_thread_check(self._b, int(thread_check))
        self.n_rows = lib.wf_rl_batch_rows(self._b)
        if bounds is not None:
            low, high = (np.ascontiguousarray(a.reshape(-1) if a.size == self.n_rows else
                                              np.broadcast_to(a, (self.n_rows,)))
                         for a in (np.asarray(x, np.float64) for x in bounds))
            e = WfError()
            rc = lib.wf_rl_batch_set_bounds(self._b, low.ctypes.data, high.ctypes.data, C.byref(e))
            if rc:
                self.close()
                check(rc, e)
        self._errs = (WfError * n)()
        # obs, reward and info as views of one buffer: a caller keeping a step's results copies it once (out)
        k = 3 * self.n_rows
        self.out = np.empty(k + n + n * len(INFO))
        self.obs, self.reward = self.out[:k].reshape(self.n_rows, 3), self.out[k:k + n]
        self.info = self.out[k + n:].reshape(n, len(INFO))
        self._args = (self.obs.ctypes.data, self.reward.ctypes.data, self.info.ctypes.data, C.addressof(self._errs))
        lib.wf_rl_batch_observe(self._b, self.obs.ctypes.data)
        # The previous action's accelerations (NaN: none), a view of the batch's array: writable.
        self.prev_accel = np.ctypeslib.as_array(lib.wf_rl_batch_prev_accel(self._b), (self.n_rows,))

    def step(self, actions, threads):
        """Set every run's commands (n_rows values, runs one after the other), step, and return (obs (n_rows, 3),
        reward (n_runs,), info (n_runs, len(INFO)))."""
        u = np.ascontiguousarray(actions, dtype=np.float64)
        if u.size != self.n_rows:
            raise _lib.WavefuelError(f"{u.size} actions for the batch's {self.n_rows} automated vehicles")
        self._raise(lib.wf_rl_batch_step(self._b, u.ctypes.data, int(threads), *self._args))
        return self.obs, self.reward, self.info

    def stepper(self, u, threads):
        """step() as a call without arguments, for a caller that steps many times: the commands are read from u (a
        float64 C-contiguous array of n_rows values, which the caller fills before each call), the results are in
        self.obs, self.reward and self.info. Valid while the batch lives (close() ends it)."""
        if not (isinstance(u, np.ndarray) and u.dtype == np.float64 and u.flags.c_contiguous and u.size == self.n_rows):
            raise ValueError(f"stepper: the commands must be a C-contiguous float64 array of {self.n_rows} values")
        # the arguments as one struct (rl.h: WfRlCall): ctypes converts one argument instead of seven
        args = _lib.WfRlCall(self._b.value, u.ctypes.data, int(threads), *self._args)
        call = functools.partial(lib.wf_rl_batch_call, C.addressof(args))

        def step():
            rc = call()
            if rc:
                self._raise(rc)
        step.commands, step.args = u, args  # what the call's addresses point to stays alive with it
        return step

    def _raise(self, rc):
        if rc:
            k = next((i for i, e in enumerate(self._errs) if e.code), 0)
            raise _lib.WavefuelError(self._errs[k].msg.decode(errors="replace"), rc)

    def thread_check(self):
        """Calls between the thread governor's probes (0: never probes)."""
        return lib.wf_rl_batch_thread_check(self._b)

    def gang_calls(self):
        """Calls so far whose steps the runs took side by side in shared blocks of the kernel (rings of at most 256
        vehicles with the same kernel; include/wavefuel/rl.h): the same bits as one by one."""
        return lib.wf_rl_batch_gang_calls(self._b)

    def governor(self):
        """(probes, switches) of the thread governor so far."""
        p, s = C.c_long(), C.c_long()
        lib.wf_rl_batch_governor(self._b, C.byref(p), C.byref(s))
        return p.value, s.value

    def close(self):
        if self._b:
            lib.wf_rl_batch_destroy(C.byref(self._b))

    def __del__(self):
        self.close()
