"""The load the benchmarks run beside a case to show how it fares on a shared machine (bench/corridor_threads,
bench/rl_envs --load): CPU-bound processes that stop themselves."""
import subprocess


def start_load(seconds, n=2):
    """n busy loops (separate Python processes) that stop themselves after `seconds`; kill and wait for them when
    done with them."""
    busy = "import time\nt = time.time() + %g\nwhile time.time() < t: pass\n" % seconds
    return [subprocess.Popen(["/usr/bin/python3", "-c", busy]) for _ in range(n)]


def beside_load(fn, seconds, n=2):
    """fn() with n busy loops (start_load) running beside it; the loops are killed and waited for however fn ends."""
    procs = start_load(seconds, n)
    try:
        return fn()
    finally:
        for p in procs:
            p.kill()
            p.wait()
