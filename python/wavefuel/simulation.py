"""A run of a scenario, ring or corridor, stepped from Python (the engine's wf_sim_begin / wf_sim_step: any
sequence of steps gives the bits of `wavefuel run`), its state as numpy views of the engine's arrays, its HDF5
result and its summary."""
import collections
import ctypes as C
import os

import numpy as np

from . import _lib
from ._lib import WfError, WfOutput, check, lib, text
from .scenario import Scenario

Quantity = collections.namedtuple("Quantity", "value units")

# Boundary index of the summary's field descriptions (WfSummaryBoundary).
_BOUNDARY = {"ring": 0, "corridor": 1}
_SUMMARY_LONG, _SUMMARY_F64 = 2, 0


class _Run:
    """The C objects of one run: the engine, the result writer and its callbacks, and the scenario the engine
    borrows. Freed once: by Simulation.close(), or when nothing refers to it any more (the Simulation and every
    state view hold it, so garbage collection never frees memory a view still shows)."""

    def __init__(self, scenario):
        self.scenario = scenario
        self.ptr, self.h5, self.ops = C.c_void_p(), C.c_void_p(), WfOutput()

    def free(self):
        if self.h5:
            lib.wf_h5out_destroy(C.byref(self.h5))
        if self.ptr:
            lib.wf_sim_destroy(C.byref(self.ptr))

    def __del__(self):
        self.free()


def _view(ptr, n, run):
    """Read-only numpy view (no copy) of n elements at a ctypes pointer, keeping `run` alive."""
    arr = (ptr._type_ * n).from_address(C.cast(ptr, C.c_void_p).value)
    arr._run = run
    a = np.ctypeslib.as_array(arr)
    a.flags.writeable = False  # the engine owns the state
    return a


class _Threads:
    """OpenMP threads of the calling thread set to the run's for the duration of a call, then restored (the
    engine's parallel loops without their own thread count read this setting)."""

    def __init__(self, n):
        self.n = n

    def __enter__(self):
        self.saved = _lib.max_threads()
        if self.n:
            _lib.set_threads(self.n)

    def __exit__(self, *exc):
        _lib.set_threads(self.saved)


class Simulation:
    """The run of `scenario` (a Scenario, or a path loaded with no overrides) on `threads` OpenMP threads (None:
    $OMP_NUM_THREADS or all cores, as `wavefuel run`). `output`: the HDF5 result to write (created when the first
    step is taken; run(output=...) may give it instead). force: replace an existing result.

    Lifetime: the run holds its scenario; close() (or the end of a `with` block, or garbage collection) frees the
    engine and the writer. A result not completed is removed when the run is closed before its end, unless
    finish() was called (which leaves FILE.h5.partial and a checkpoint, as an interrupted `wavefuel run`)."""

    def __init__(self, scenario, threads=None, output=None, force=False):
        self.scenario = scenario if isinstance(scenario, Scenario) else Scenario.load(scenario)
        if threads is not None and not 1 <= int(threads) <= 4096:  # the range of `wavefuel run --threads`
            raise _lib.WavefuelError(f"threads must be an integer in [1, 4096] (got {threads})")
        self._run = _Run(self.scenario)
        self._begun = False
        self.output, self.force = output, force
        err = WfError()
        with _Threads(threads):
            check(lib.wf_sim_create(self.scenario._ptr, C.byref(self._run.ptr), C.byref(err)), err)
        self.threads = lib.wf_sim_threads(self._ptr)
        self.kind = text(lib.wf_sim_kind(self._ptr))
        self._ring_state = self._fleet_views() if self.kind == "ring" else None

    # ------------------------------------------------------------------------------------- stepping
    def _begin(self):
        if self._begun:
            return
        err = WfError()
        ops = None
        if self.output is not None:
            path = os.fspath(self.output)
            check(lib.wf_h5out_create(self._ptr, path.encode(), int(bool(self.force)), C.byref(self._run.h5),
                                      C.byref(self._run.ops), C.byref(err)), err)
            ops = C.byref(self._run.ops)
        check(lib.wf_sim_begin(self._ptr, ops, C.byref(err)), err)
        self._begun = True

    def step(self, n=1):
        """Advance n steps (fewer at the end). A run is duration_s / dt_s steps and then the record of its final
        instant: the call after the last step takes that record, writes the summary and completes the result file.
        Raises WavefuelError after the end. The steps run in C without
        returning to Python: Ctrl-C (KeyboardInterrupt) takes effect when the call returns."""
        self._alive()
        if int(n) < 1:
            raise _lib.WavefuelError(f"{self.scenario.path}: step(n): n must be at least 1 (got {n})")
        self._begin()
        err = WfError()
        with _Threads(self.threads):
            check(lib.wf_sim_step(self._ptr, int(n), C.byref(err)), err)
        return self

    def run(self, output=None, force=None):
        """Run to the end; returns the summary. output: the result file (only before the first step; default the
        one given to the constructor, else none is written: use scenario.output_path for `wavefuel run`'s
        default)."""
        self._alive()
        if output is not None:
            if self._begun:
                raise _lib.WavefuelError(f"{self.scenario.path}: the run has begun: give output= before the first "
                                         "step (Simulation(..., output=...))")
            self.output = output
        if force is not None:
            self.force = force
        if not self.done:
            self.step(self.scenario.n_steps + 1)
        return self.summary

    def finish(self):
        """End the run before its end: the result stays as FILE.h5.partial with a checkpoint that `wavefuel run
        --resume` continues ("stopped by the caller")."""
        self._alive()
        self._begin()
        err = WfError()
        rc = lib.wf_sim_finish(self._ptr, C.byref(err))
        if rc not in (0, 3):  # WF_EINTR: stopped as asked
            check(rc, err)

    @property
    def t(self):
        """Simulated time now, s (steps done x dt)."""
        self._alive()
        return lib.wf_sim_time_s(self._ptr)

    @property
    def steps_done(self):
        self._alive()
        return lib.wf_sim_steps_done(self._ptr)

    @property
    def done(self):
        """True once the run has ended."""
        self._alive()
        return bool(lib.wf_sim_done(self._ptr))

    @property
    def wall_s(self):
        """Wall time of the step loop so far, s (the steps an RL batch takes, as an environment's, are not timed)."""
        self._alive()
        return lib.wf_sim_wall_s(self._ptr)

    @property
    def result_path(self):
        """The file written ("x.h5" once completed, "x.h5.partial" otherwise; None without output)."""
        return text(lib.wf_h5out_path(self._h5)) or None if self._h5 else None

    # ---------------------------------------------------------------------------------------- state
    def _fleet_views(self):
        f = lib.wf_sim_fleet(self._ptr).contents
        names = ("x_m", "v_mps", "class_id", "group_id", "fuel_g", "a_mps2", "gap_m", "v_lead_mps", "theta_rad",
                 "fuel_rate_gps", "flag")
        views = {k: _view(getattr(f, k), f.n, self._run) for k in names if getattr(f, k)}
        if f.n_lanes > 1:  # a multi-lane ring: each slot's lane and vehicle
            views["lane"] = _view(f.lane, f.n, self._run)
            views["vehicle"] = _view(f.id, f.n, self._run)
        return views

    def state(self):
        """The vehicles now, as a dict of numpy arrays (read-only).

        Ring: views of the fleet's arrays in ring order (vehicle i + 1 leads vehicle i), the same arrays for the
        whole run, changing in place as the run steps: x_m (unwrapped front-bumper position), v_mps, class_id,
        group_id (indices into scenario.classes / scenario.groups), fuel_g (fuel burnt in the statistics window,
        0 before the warm-up ends); a_mps2, gap_m, v_lead_mps, theta_rad, fuel_rate_gps, flag only where the run
        keeps them fleet-wide (two-pass steps: SUNDIALS integrators, trajectories, time.fused_step false).
        A multi-lane ring (road.lanes > 1) orders its slots by lane (0 the rightmost), then along the lane (slot
        i + 1 leads slot i within a lane, the lane's first slot leads its last, one lap ahead); vehicles move
        between slots when they change lanes, and two more views say what each slot holds now: lane, and vehicle
        (the vehicle's index in the fleet at the start, as in the result file).

        Corridor: the vehicles on the road now in road order (index 0 the front, most downstream, vehicle; each
        vehicle's leader is the previous one): x_m (from the entrance), v_mps, a_mps2, gap_m, v_lead_mps,
        theta_rad, fuel_rate_gps, flag, length_m, serial (arrival number), class_id, group_id. Vehicles live in a
        circular buffer of slots: the arrays are views (reversed slices) while the vehicles occupy one contiguous
        run of slots, and copies when that run wraps around the buffer's end. Either way they describe the
        vehicles present when state() was called: call it again after stepping. A corridor of several lanes gives
        its lanes one after the other (lane 0 first, each in road order) as copies, with `lane` (docs/lanes.md)."""
        self._alive()
        if self._ring_state is not None:
            return dict(self._ring_state)
        corr = lib.wf_sim_corridor(self._ptr)
        names = ("x_m", "v_mps", "a_mps2", "gap_m", "v_lead_mps", "theta_rad", "fuel_rate_gps", "flag", "length_m",
                 "serial", "class_id", "group_id")
        lanes = []
        for lane in range(lib.wf_corridor_n_lanes(corr)):
            vh = lib.wf_corridor_lane(corr, lane).contents
            first, n, cap = vh.first, vh.n, vh.cap
            out = {}
            for k in names:
                buf = _view(getattr(vh, k), cap, self._run)
                if first + n <= cap:  # one contiguous run: slots first .. first + n - 1, back to front
                    out[k] = buf[first:first + n][::-1]
                else:
                    out[k] = np.concatenate((buf[:first + n - cap][::-1], buf[first:][::-1]))
            out["lane"] = np.full(n, lane, dtype=np.uint8)
            lanes.append(out)
        if len(lanes) == 1:
            del lanes[0]["lane"]
            return lanes[0]
        return {k: np.concatenate([ln[k] for ln in lanes]) for k in lanes[0]}

    @property
    def n_vehicles(self):
        """Vehicles in the fleet (ring) or on the road now (corridor)."""
        self._alive()
        if self._ring_state is not None:
            return self._ring_state["x_m"].size
        return lib.wf_corridor_vehicles(lib.wf_sim_corridor(self._ptr)).contents.n

    # ------------------------------------------------------------------------- external controllers
    def group_index(self, group):
        """The index of a driver group given by name or index (scenario.groups)."""
        if isinstance(group, str):
            if group not in self.scenario.groups:
                raise _lib.WavefuelError(f"{self.scenario.path}: no driver group '{group}' (groups: "
                                         f"{', '.join(self.scenario.groups)})")
            return self.scenario.groups.index(group)
        g = int(group)
        if not 0 <= g < len(self.scenario.groups):
            raise _lib.WavefuelError(f"{self.scenario.path}: no driver group {g} (the scenario has "
                                     f"{len(self.scenario.groups)})")
        return g

    def group_size(self, group):
        """Vehicles of the driver group on the road now (a ring: all of them)."""
        self._alive()
        return lib.wf_sim_group_size(self._ptr, self.group_index(group))

    def observe(self, group):
        """The inputs of the next step for each vehicle of an external group (model `external`,
        `external_speed`, or `mlp`: the rows its network reads; docs/controllers.md), in road order (a ring:
        increasing position; a corridor: front first): an (n, 3) array of [own speed m/s, leader speed m/s,
        bumper-to-bumper gap m], exactly as the engine computes them."""
        self._alive()
        g = self.group_index(group)
        n = lib.wf_sim_group_size(self._ptr, g)
        obs = np.empty((n, 3))
        err = WfError()
        check(lib.wf_sim_observe(self._ptr, g, obs.ctypes.data_as(C.POINTER(C.c_double)), n, C.byref(err)), err)
        return obs

    def set_actions(self, group, actions):
        """Set each vehicle's command for the next steps (held until set again), in observe()'s order: the
        acceleration (m/s^2, model `external`) or the set speed (m/s, `external_speed`); NaN: none (the vehicle
        drives as `acc`). The group's noise, limits and feasible-acceleration rule apply as to any model. An `mlp`
        group is refused: its network sets the commands."""
        self._alive()
        g = self.group_index(group)
        a = np.ascontiguousarray(actions, dtype=np.float64).ravel()
        err = WfError()
        check(lib.wf_sim_set_actions(self._ptr, g, a.ctypes.data_as(C.POINTER(C.c_double)), a.size,
                                     C.byref(err)), err)

    # -------------------------------------------------------------------------------------- summary
    @property
    def summary(self):
        """The run's summary once it has ended (docs/metrics.md): {name: Quantity(value, units)} with the fields
        of /summary for this road, "classes": {class name: {name: Quantity}} with the per-class fields and, when
        some driver group has a safety filter (docs/controllers.md#safety-filters), "groups": {group name:
        {name: Quantity}} with the per-group fields (its filter's interventions)."""
        self._alive()
        if not self.done:
            raise _lib.WavefuelError(f"{self.scenario.path}: the summary exists once the run has ended "
                                     f"(t = {self.t:g} s of {self.scenario.duration_s:g} s)")
        b = _BOUNDARY[self.kind]
        s = lib.wf_sim_summary(self._ptr)
        base = C.cast(s, C.c_void_p).value

        def values(fields, addr):
            out = {}
            for f in fields:
                if f.desc[b] is None or not lib.wf_summary_field_on(C.byref(f), self.scenario._ptr):
                    continue
                v = lib.wf_summary_value(addr, C.byref(f))
                out[text(f.name)] = Quantity(v if f.type == _SUMMARY_F64 else int(v), text(f.units))
            return out

        res = values(_lib.table("wf_summary_fields", _lib.WfSummaryField, "wf_summary_n_fields"), base)
        cls_fields = _lib.table("wf_summary_class_fields", _lib.WfSummaryField, "wf_summary_n_class_fields")
        cls0 = base + _lib.WfSummary.cls.offset
        res["classes"] = {name: values(cls_fields, cls0 + k * C.sizeof(_lib.WfClassSummary))
                          for k, name in enumerate(self.scenario.classes)}
        grp_fields = _lib.table("wf_summary_group_fields", _lib.WfSummaryField, "wf_summary_n_group_fields")
        grp0 = base + _lib.WfSummary.grp.offset
        groups = {name: values(grp_fields, grp0 + k * C.sizeof(_lib.WfGroupSummary))
                  for k, name in enumerate(self.scenario.groups)}
        if any(groups.values()):
            res["groups"] = groups
        return res

    # ------------------------------------------------------------------------------------- lifetime
    @property
    def _ptr(self):
        return self._run.ptr

    @property
    def _h5(self):
        return self._run.h5

    def _alive(self):
        if not self._ptr:
            raise _lib.WavefuelError("this Simulation is closed")

    def close(self):
        """Free the writer (an unfinished result is removed) and the engine now. Views from state() must not be
        used afterwards (without close(), the run lives as long as the Simulation or any of its views)."""
        if getattr(self, "_run", None):
            self._run.free()
        self._ring_state = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return (f"<wavefuel.Simulation {self.scenario.name} ({self.kind}, {self.threads} threads) t = "
                f"{lib.wf_sim_time_s(self._ptr) if self._ptr else float('nan'):g} s>")
