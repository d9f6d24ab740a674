"""libwavefuel.so through ctypes: where the library is found, the C structures the package reads (mirrors of
include/wavefuel/*.h; tests/python/layout.py checks every offset against the C compiler's), the functions'
signatures, errors, and the process-wide settings the library leaves to its programs (src/cli/process.c does the
same for bin/wavefuel): the vehicle class search path and HDF5's error printing."""
import ctypes as C
import os

PACKAGE_DIR = os.path.dirname(os.path.abspath(__file__))
# The checkout this package sits in, when it is run from one (python/wavefuel -> the repository).
CHECKOUT_DIR = os.path.dirname(os.path.dirname(PACKAGE_DIR))

WF_MAX_CLASSES = 16
WF_MAX_GROUPS = 16
WF_MAX_LANES = 8
WF_MAX_LC_PARAMS = 8
WF_MAX_MODEL_PARAMS = 32
WF_MAX_SAFETY_PARAMS = 8
WF_EINPUT = 2


class WavefuelError(Exception):
    """A failure reported by wavefuel: `code` is its status (2 bad input, 1 system or library, 3 interrupted) and
    the message is wavefuel's own (file, line or key, and value)."""

    def __init__(self, message, code=WF_EINPUT):
        super().__init__(message)
        self.code = code


WavefuelError.__module__ = "wavefuel"  # shown as wavefuel.WavefuelError in tracebacks


def library_path():
    """The shared library used: $WAVEFUEL_LIB, else libwavefuel.so next to the package (`make python` copies it
    there), else the checkout's lib/libwavefuel.so."""
    env = os.environ.get("WAVEFUEL_LIB")
    if env:
        return env
    for p in (os.path.join(PACKAGE_DIR, "libwavefuel.so"), os.path.join(CHECKOUT_DIR, "lib", "libwavefuel.so")):
        if os.path.exists(p):
            return p
    raise ImportError("wavefuel: libwavefuel.so not found: set $WAVEFUEL_LIB, or run `make python` in the checkout "
                      f"(looked in {PACKAGE_DIR} and {os.path.join(CHECKOUT_DIR, 'lib')})")


# ------------------------------------------------------------------------------------------- structures
class WfError(C.Structure):
    _fields_ = [("code", C.c_int), ("msg", C.c_char * 1024)]


class WfParamSpec(C.Structure):
    _fields_ = [("key", C.c_char_p), ("offset", C.c_size_t), ("def_", C.c_double), ("min", C.c_double),
                ("max", C.c_double), ("unit", C.c_char_p), ("flags", C.c_int), ("doc", C.c_char_p)]


EVAL_FN = C.CFUNCTYPE(None, C.c_void_p, C.c_size_t, C.c_void_p, C.c_void_p, C.c_void_p, C.c_int, C.c_void_p,
                      C.c_void_p)
AMAX_FN = C.CFUNCTYPE(C.c_double, C.c_void_p, C.c_double, C.c_double)


class WfEnergyModel(C.Structure):
    _fields_ = [("name", C.c_char_p), ("param_size", C.c_size_t), ("spec", C.POINTER(WfParamSpec)),
                ("n_spec", C.c_size_t), ("check", C.c_void_p), ("eval", EVAL_FN), ("a_max", AMAX_FN),
                ("load", C.c_void_p), ("release", C.c_void_p), ("n_outside", C.c_void_p),
                ("project_default", C.c_int), ("eval_flat", C.c_void_p)]


class WfVehicleClass(C.Structure):
    _fields_ = [("name", C.c_char * 64), ("label", C.c_char * 96), ("path", C.c_char * 1024), ("duty", C.c_int),
                ("fuel", C.c_int), ("mass_kg", C.c_double), ("paper_mass_kg", C.c_double),
                ("length_m", C.c_double), ("fuel_density_g_per_l", C.c_double), ("kw_per_gps", C.c_double),
                ("model", C.POINTER(WfEnergyModel)), ("params", C.c_void_p)]


class WfRoad(C.Structure):
    _fields_ = [("length_m", C.c_double), ("speed_limit_mps", C.c_double), ("n_grade", C.c_size_t),
                ("grade_x_m", C.c_void_p), ("grade_rad", C.c_void_p)]


class WfOdeConfig(C.Structure):
    _fields_ = [("kind", C.c_int), ("bdf", C.c_int), ("erk_table", C.c_char * 64), ("rtol", C.c_double),
                ("atol_x_m", C.c_double), ("atol_v_mps", C.c_double), ("atol_fuel_g", C.c_double),
                ("max_step_s", C.c_double), ("max_steps", C.c_long), ("fuel_errcon", C.c_int),
                ("rk4_substeps", C.c_int), ("fixed_step_s", C.c_double), ("nvector_openmp", C.c_int)]


class WfClassShare(C.Structure):
    _fields_ = [("vc", WfVehicleClass), ("fraction", C.c_double), ("count", C.c_long), ("length_m", C.c_double),
                ("indices", C.c_void_p), ("n_indices", C.c_size_t)]


class WfCfModel(C.Structure):
    _fields_ = [("name", C.c_char_p), ("doc", C.c_char_p), ("param_size", C.c_size_t),
                ("spec", C.POINTER(WfParamSpec)), ("n_spec", C.c_size_t)]  # a prefix: the rest is not read


class WfDriverGroup(C.Structure):
    _fields_ = [("name", C.c_char * 64), ("model", C.POINTER(WfCfModel)),
                ("params", C.c_double * WF_MAX_MODEL_PARAMS), ("spread", C.c_double * WF_MAX_MODEL_PARAMS),
                ("dist", C.c_int), ("fraction", C.c_double), ("count", C.c_long), ("noise_mps2", C.c_double),
                ("accel_max_mps2", C.c_double), ("decel_max_mps2", C.c_double), ("clip_feasible", C.c_int),
                ("indices", C.c_void_p), ("n_indices", C.c_size_t), ("placement", C.c_int),
                ("class_index", C.c_int), ("plugin", C.c_void_p), ("mlp", C.c_void_p),
                ("safety", C.c_void_p),
                ("safety_params", C.c_double * WF_MAX_SAFETY_PARAMS), ("lc", C.c_void_p),
                ("lc_params", C.c_double * WF_MAX_LC_PARAMS)]


class WfScenario(C.Structure):
    _fields_ = [("path", C.c_char * 1024), ("text", C.c_char_p), ("overrides", C.c_char_p),
                ("name", C.c_char * 128), ("road", WfRoad), ("duration_s", C.c_double), ("dt_s", C.c_double),
                ("output_interval_s", C.c_double), ("warmup_s", C.c_double), ("integrator", C.c_char * 32),
                ("adaptive", C.c_int), ("solver", WfOdeConfig), ("fused_step", C.c_int), ("block_steps", C.c_int),
                ("tile_vehicles", C.c_long), ("thread_check_steps", C.c_long), ("seed", C.c_uint64),
                ("n_vehicles", C.c_long), ("n_lanes", C.c_int), ("lane_rule", C.c_int),
                ("lane_counts", C.c_long * WF_MAX_LANES), ("lane_speed_limit_mps", C.c_double * WF_MAX_LANES),
                ("placement", C.c_int),
                ("classes", WfClassShare * WF_MAX_CLASSES), ("n_classes", C.c_size_t),
                ("groups", WfDriverGroup * WF_MAX_GROUPS), ("n_groups", C.c_size_t), ("init_state", C.c_int),
                ("perturb_vehicle", C.c_long)] + [(f, C.c_double) for f in (
                    "perturb_dx_m", "perturb_dv_mps", "jitter_m", "v_stop_mps", "v_go_mps", "hard_brake_mps2",
                    "wave_speed_mps")] + [
                ("output_path", C.c_char * 1024), ("trajectories", C.c_int), ("trajectory_interval_s", C.c_double),
                ("corridor", C.c_void_p), ("inputs", C.c_void_p), ("n_inputs", C.c_size_t)]


_dp = C.POINTER(C.c_double)
_u16p = C.POINTER(C.c_uint16)
_u32p = C.POINTER(C.c_uint32)
_u8p = C.POINTER(C.c_uint8)


class WfFleet(C.Structure):
    _fields_ = [("n", C.c_size_t), ("x_m", _dp), ("v_mps", _dp), ("multipass", C.c_int), ("a_mps2", _dp),
                ("gap_m", _dp), ("v_lead_mps", _dp), ("theta_rad", _dp), ("fuel_rate_gps", _dp), ("flag", _u8p),
                ("grade_seg", _u32p), ("class_id", _u16p), ("group_id", _u16p), ("slot", _u32p),
                ("class_length_m", C.c_double * WF_MAX_CLASSES), ("n_groups", C.c_size_t),
                ("group_n", C.c_size_t * WF_MAX_GROUPS), ("group_params", C.c_void_p * WF_MAX_GROUPS),
                ("group_param_stride", C.c_size_t * WF_MAX_GROUPS), ("group_state", C.c_void_p * WF_MAX_GROUPS),
                ("n_classes", C.c_size_t), ("class_n", C.c_size_t * WF_MAX_CLASSES), ("window_open", C.c_int),
                ("x_start_m", _dp), ("fuel_g", _dp), ("sum_v", _dp), ("sum_v2", _dp), ("sum_a", _dp),
                ("sum_a2", _dp), ("stopped_steps", _u32p), ("stops", _u32p), ("hard_brakes", _u32p),
                ("infeasible_steps", _u32p), ("mode", _u8p), ("v_init_mps", C.c_double),
                ("n_lanes", C.c_size_t), ("lane_n", C.c_size_t * WF_MAX_LANES), ("lane", _u8p), ("id", _u32p),
                ("pos", _u32p), ("lc_ready_step", C.POINTER(C.c_int64)), ("lane_changes", _u32p), ("cut_ins", _u32p),
                ("lap_m", _dp), ("share_lo", C.c_size_t), ("share_hi", C.c_size_t)]


class WfCorridorVehicles(C.Structure):
    _fields_ = [("cap", C.c_size_t), ("first", C.c_size_t), ("n", C.c_size_t), ("x_m", _dp), ("v_mps", _dp),
                ("a_mps2", _dp), ("gap_m", _dp), ("v_lead_mps", _dp), ("theta_rad", _dp),
                ("fuel_rate_gps", _dp), ("flag", _u8p), ("length_m", _dp), ("serial", C.POINTER(C.c_uint64)),
                ("class_id", _u16p), ("group_id", _u16p), ("params", _dp), ("state", C.c_void_p)]


class WfCorridorCounts(C.Structure):
    _fields_ = [("arrived", C.c_int64), ("entered", C.c_int64), ("exited", C.c_int64), ("queued", C.c_int64),
                ("delayed", C.c_int64), ("max_queue", C.c_int64), ("queue_delay_s", C.c_double),
                ("overlaps", C.c_int64), ("off_ramp", C.c_int64), ("missed_exits", C.c_int64)]


class WfClassSummary(C.Structure):
    _fields_ = [("count", C.c_long), ("entered", C.c_int64), ("trips", C.c_int64)] + [
        (f, C.c_double) for f in ("fuel_g", "dist_m", "l_per_100km", "mpg", "infeasible_share", "stops_per_vkm",
                                  "g_per_km_up", "g_per_km_down", "g_per_km_flat", "trip_fuel_mean_g",
                                  "trip_time_mean_s")]


class WfGroupSummary(C.Structure):
    _fields_ = [("safety_steps", C.c_int64), ("safety_interventions", C.c_int64), ("safety_share", C.c_double)]


class WfSummary(C.Structure):
    _fields_ = [(f, C.c_double) for f in (
        "window_s", "fuel_g", "dist_m", "vkt_km", "vht_h", "l_per_100km", "mpg", "stops_per_vkm",
        "hard_brakes_per_vkm", "mean_speed_mps", "sd_speed_time_avg_mps", "throughput_vph", "inflow_vph",
        "outflow_vph", "infeasible_share", "time_stopped_share")] + [
        ("overlaps", C.c_int64), ("trips", C.c_int64), ("mean_travel_time_s", C.c_double),
        ("mean_trip_fuel_g", C.c_double), ("mean_queue_delay_s", C.c_double), ("counts", WfCorridorCounts),
        ("on_road", C.c_int64), ("cls", WfClassSummary * WF_MAX_CLASSES), ("safety_interventions", C.c_int64),
        ("collisions_repaired", C.c_int64), ("grp", WfGroupSummary * WF_MAX_GROUPS), ("lane_changes", C.c_int64),
        ("cut_ins", C.c_int64)]


class WfSummaryPrint(C.Structure):
    _fields_ = [("label", C.c_char_p), ("format", C.c_char_p), ("suffix", C.c_char_p)]


class WfSummaryField(C.Structure):
    _fields_ = [("name", C.c_char_p), ("units", C.c_char_p), ("desc", C.c_char_p * 2), ("type", C.c_int),
                ("offset", C.c_size_t), ("fleet_offset", C.c_size_t), ("print", WfSummaryPrint * 2),
                ("print_mul", C.c_double), ("print_div", C.c_double), ("sweep_only", C.c_int), ("when", C.c_int)]


class WfOutput(C.Structure):
    _fields_ = [(f, C.c_void_p) for f in ("begin", "record", "trajectory", "trips", "checkpoint", "end", "ctx")]


class WfRlReward(C.Structure):
    _fields_ = [("scope_all", C.c_int)] + [(f, C.c_double) for f in ("w_fuel", "gap_min_m", "gap_max_m", "w_gap",
                                                                      "w_accel", "w_jerk")]


class WfRlCall(C.Structure):
    _fields_ = [("b", C.c_void_p), ("actions", C.c_void_p), ("threads", C.c_int), ("obs", C.c_void_p),
                ("reward", C.c_void_p), ("info", C.c_void_p), ("errs", C.c_void_p)]


# The structures whose layout tests/python/layout.py compares with the C compiler's.
MIRRORS = (WfError, WfParamSpec, WfEnergyModel, WfVehicleClass, WfRoad, WfOdeConfig, WfClassShare, WfDriverGroup,
           WfFleet, WfCorridorVehicles, WfCorridorCounts, WfClassSummary, WfGroupSummary, WfSummary, WfSummaryPrint,
           WfSummaryField, WfOutput, WfScenario, WfRlReward, WfRlCall)
# Prefix mirrors: only their fields' offsets are compared, not their sizes.
PREFIXES = (WfCfModel,)

# ------------------------------------------------------------------------------------------- functions
_vp = C.c_void_p
_err = C.POINTER(WfError)
_SIGNATURES = {
    "wf_scenario_load": (C.c_int, [C.c_char_p, C.POINTER(C.c_char_p), C.c_size_t, C.POINTER(_vp), _err]),
    "wf_scenario_load_text": (C.c_int, [C.c_char_p, C.c_char_p, C.POINTER(C.c_char_p), C.c_size_t, C.POINTER(_vp),
                                        _err]),
    "wf_scenario_destroy": (None, [C.POINTER(_vp)]),
    "wf_scenario_n_steps": (C.c_long, [_vp]),
    "wf_sim_create": (C.c_int, [_vp, C.POINTER(_vp), _err]),
    "wf_sim_destroy": (None, [C.POINTER(_vp)]),
    "wf_sim_begin": (C.c_int, [_vp, C.POINTER(WfOutput), _err]),
    "wf_sim_step": (C.c_int, [_vp, C.c_long, _err]),
    "wf_sim_finish": (C.c_int, [_vp, _err]),
    "wf_sim_done": (C.c_int, [_vp]),
    "wf_sim_time_s": (C.c_double, [_vp]),
    "wf_sim_kind": (C.c_char_p, [_vp]),
    "wf_sim_fleet": (C.POINTER(WfFleet), [_vp]),
    "wf_sim_corridor": (_vp, [_vp]),
    "wf_sim_summary": (C.POINTER(WfSummary), [_vp]),
    "wf_sim_wall_s": (C.c_double, [_vp]),
    "wf_sim_steps_done": (C.c_long, [_vp]),
    "wf_sim_threads": (C.c_int, [_vp]),
    "wf_sim_group_size": (C.c_size_t, [_vp, C.c_size_t]),
    "wf_sim_observe": (C.c_int, [_vp, C.c_size_t, C.POINTER(C.c_double), C.c_size_t, _err]),
    "wf_sim_set_actions": (C.c_int, [_vp, C.c_size_t, C.POINTER(C.c_double), C.c_size_t, _err]),
    "wf_sims_step": (C.c_int, [_vp, C.c_size_t, C.c_long, C.c_int, _vp]),
    "wf_sims_observe": (C.c_int, [_vp, C.c_size_t, _vp, _vp, C.c_size_t, _err]),
    "wf_sims_set_actions": (C.c_int, [_vp, C.c_size_t, _vp, _vp, C.c_size_t, _err]),
    "wf_rl_batch_create": (C.c_int, [_vp, C.c_size_t, _vp, C.POINTER(WfRlReward), C.c_long, C.c_double,
                                     C.POINTER(_vp), _err]),
    "wf_rl_batch_destroy": (None, [C.POINTER(_vp)]),
    "wf_rl_batch_rows": (C.c_size_t, [_vp]),
    "wf_rl_batch_observe": (None, [_vp, _vp]),
    "wf_rl_batch_prev_accel": (C.POINTER(C.c_double), [_vp]),
    "wf_rl_batch_step": (C.c_int, [_vp, _vp, C.c_int, _vp, _vp, _vp, _vp]),
    "wf_rl_batch_call": (C.c_int, [_vp]),
    "wf_rl_batch_set_bounds": (C.c_int, [_vp, _vp, _vp, C.POINTER(WfError)]),
    "wf_rl_batch_set_thread_check": (None, [_vp, C.c_long]),
    "wf_rl_batch_thread_check": (C.c_long, [_vp]),
    "wf_rl_batch_gang_calls": (C.c_long, [_vp]),
    "wf_rl_batch_governor": (None, [_vp, C.POINTER(C.c_long), C.POINTER(C.c_long)]),
    "wf_corridor_vehicles": (C.POINTER(WfCorridorVehicles), [_vp]),
    "wf_corridor_n_lanes": (C.c_size_t, [_vp]),
    "wf_corridor_lane": (C.POINTER(WfCorridorVehicles), [_vp, C.c_size_t]),
    "wf_corridor_counts": (C.POINTER(WfCorridorCounts), [_vp]),
    "wf_h5out_create": (C.c_int, [_vp, C.c_char_p, C.c_int, C.POINTER(_vp), C.POINTER(WfOutput), _err]),
    "wf_h5out_destroy": (None, [C.POINTER(_vp)]),
    "wf_h5out_path": (C.c_char_p, [_vp]),
    "wf_vehicle_search_path_set": (C.c_int, [C.c_char_p, _err]),
    "wf_vehicle_search_path": (C.c_char_p, []),
    "wf_vehicle_find": (C.c_int, [C.c_char_p, C.POINTER(WfVehicleClass), _err]),
    "wf_vehicle_list": (C.c_int, [C.POINTER(C.POINTER(WfVehicleClass)), C.POINTER(C.c_size_t), _err]),
    "wf_vehicle_free": (None, [C.POINTER(WfVehicleClass)]),
    "wf_summary_value": (C.c_double, [_vp, C.POINTER(WfSummaryField)]),
    "wf_mlp_load": (C.c_int, [C.c_char_p, C.POINTER(_vp), _err]),
    "wf_mlp_destroy": (None, [C.POINTER(_vp)]),
    "wf_mlp_eval": (None, [_vp, C.POINTER(C.c_double), C.c_size_t, C.POINTER(C.c_double), C.c_int]),
    "wf_mlp_output": (C.c_int, [_vp]),
    "wf_summary_field_on": (C.c_int, [C.POINTER(WfSummaryField), _vp]),
    "wf_duty_name": (C.c_char_p, [C.c_int]),
    "wf_fuel_name": (C.c_char_p, [C.c_int]),
}


def _load():
    lib = C.CDLL(library_path())
    for name, (res, args) in _SIGNATURES.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = res, args
    return lib


lib = _load()
libc = C.CDLL(None)
libc.free.argtypes, libc.free.restype = [C.c_void_p], None


def table(name, struct, count_name):
    """A C table exported by the library (name[count_name] of struct) as a ctypes array."""
    n = C.c_size_t.in_dll(lib, count_name).value
    return (struct * n).in_dll(lib, name)


def check(rc, err):
    """Raise WavefuelError with wavefuel's message when a call failed."""
    if rc:
        raise WavefuelError(err.msg.decode(errors="replace") or f"wavefuel: error {rc}", rc)


def text(b):
    return b.decode() if b is not None else None


def set_threads(n):
    """OpenMP threads of the calling thread's next parallel regions (the run reads them when it is created)."""
    lib.omp_set_num_threads.argtypes = [C.c_int]
    lib.omp_set_num_threads(int(n))


def max_threads():
    lib.omp_get_max_threads.restype = C.c_int
    return lib.omp_get_max_threads()


def set_class_path(dirs=None):
    """Set the vehicle class search path (colon-separated directories). Default: "$WAVEFUEL_VEHICLES" then the
    checkout's vehicles/, the order bin/wavefuel uses (docs/energy.md)."""
    if dirs is None:
        parts = os.environ.get("WAVEFUEL_VEHICLES", "").split(":")
        checkout = os.path.join(CHECKOUT_DIR, "vehicles")
        # The checkout's vehicles/ unless $WAVEFUEL_VEHICLES names it already (classes listed once).
        if os.path.isdir(checkout) and not any(p and os.path.realpath(p) == os.path.realpath(checkout)
                                               for p in parts):
            parts.append(checkout)
        dirs = ":".join(p for p in parts if p)
    err = WfError()
    check(lib.wf_vehicle_search_path_set(dirs.encode(), C.byref(err)), err)


def class_path():
    return lib.wf_vehicle_search_path().decode()


def _process_init():
    # As bin/wavefuel (src/cli/process.c): no HDF5 clean-up at exit (it may close a file a second time after a
    # failed close on a full disk; ignored when HDF5 is already initialised, e.g. by h5py) and no HDF5 error-stack
    # dump: wavefuel reports every HDF5 failure itself, in the exception's message.
    lib.H5dont_atexit()
    lib.H5Eset_auto2.argtypes = [C.c_int64, C.c_void_p, C.c_void_p]
    lib.H5Eset_auto2(0, None, None)  # H5E_DEFAULT
    set_class_path()


_process_init()
