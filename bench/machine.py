"""What a benchmark ran on, for its tables: the CPU model, the cores, the kernel and the first line a tool prints
about its version (`gcc --version`, `mpirun --version`). Imported by bench/scaling/run.py and bench/mpi_ring/run.py."""
import os
import platform
import subprocess


def machine(key, version_cmd, unknown):
    """dict(cpu, cores, kernel, <key>=first line of version_cmd's output, or `unknown`)."""
    cpu = "unknown CPU"
    with open("/proc/cpuinfo") as f:
        for line in f:
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    try:
        out = subprocess.run(version_cmd, capture_output=True, text=True).stdout.splitlines()
    except OSError:
        out = []
    return {"cpu": cpu, "cores": os.cpu_count(), "kernel": platform.release(), key: out[0] if out else unknown}
