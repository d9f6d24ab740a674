"""The parameters of wavefuel's ring environments, read from their loaded scenarios, for the baselines that rebuild
the same rings outside wavefuel (numpy_ring.py, sumo_ring.py): so that a change of RingEnv's defaults changes the
baselines with it."""
import ctypes as C

import numpy as np

import wavefuel as wf

IDM_KEYS = ("v0_mps", "T_s", "s0_m", "a_mps2", "b_mps2", "delta")  # src/models/cf/idm.c's parameter order


def ring_spec(envs):
    """{length_m: (B,), av: (N,) bool mask in road order, idm: the humans' (v0_mps, T_s, s0_m, a_mps2, b_mps2),
    limits: ((accel_max, decel_max) of the humans, of the automated vehicles) m/s^2, energy: the class's CIRCLES
    parameters {key: value}, car_m, dt_s, reward, action_range} of the RingEnvs `envs` after their reset (one
    vehicle class, humans in group 0 with IDM delta 4, the automated vehicles in group 1, no feasibility clip)."""
    e0 = envs[0]
    sc = C.cast(e0.sim.scenario._ptr, C.POINTER(wf._lib.WfScenario)).contents
    hum, av = sc.groups[0], sc.groups[1]
    assert [hum.model.contents.spec[k].key.decode() for k in range(6)] == list(IDM_KEYS)
    assert hum.params[5] == 4.0 and not hum.clip_feasible and not av.clip_feasible
    vc = wf.VehicleClass(e0.vehicle_class)
    return dict(length_m=[e.scenario_dict["road"]["length_m"] for e in envs],
                av=np.array(e0.sim.state()["group_id"]) == 1,
                idm=tuple(hum.params[k] for k in range(5)),
                limits=((hum.accel_max_mps2, hum.decel_max_mps2), (av.accel_max_mps2, av.decel_max_mps2)),
                energy={k: v for k, (v, _) in vc.params.items()}, car_m=vc.keys["length_m"][0], dt_s=e0.dt_s,
                reward=e0.reward, action_range=(e0.action_space.low[0], e0.action_space.high[0]))
