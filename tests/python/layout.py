#!/usr/bin/python3
"""The ctypes mirrors of python/wavefuel/_lib.py against the C compiler: every mirrored field's offset (and each
full mirror's size) computed by offsetof/sizeof in a program generated here from the mirrors' own field lists.
Prints PASS/FAIL lines. Usage: layout.py CC (run from the repository)."""
import ctypes
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, "python")
from wavefuel import _lib  # noqa: E402

HEADERS = ("energy.h", "vehicle.h", "scenario.h", "fleet.h", "corridor.h", "summary.h", "engine.h", "cf.h", "rl.h")


def main():
    cc = sys.argv[1] if len(sys.argv) > 1 else "cc"
    checks = []  # (label, ctypes value, C expression)
    for st in _lib.MIRRORS + _lib.PREFIXES:
        name = st.__name__
        for f in st._fields_:
            field = f[0].rstrip("_") if f[0] == "def_" else f[0]
            checks.append((f"{name}.{field}", getattr(st, f[0]).offset, f"offsetof({name}, {field})"))
        if st in _lib.MIRRORS:
            checks.append((f"sizeof({name})", ctypes.sizeof(st), f"sizeof({name})"))
    src = "".join(f"#include \"wavefuel/{h}\"\n" for h in HEADERS) + "#include <stdio.h>\n#include <stddef.h>\n"
    src += "int main(void)\n{\n" + "".join(f"    printf(\"%zu\\n\", (size_t)({e}));\n" for _, _, e in checks)
    src += "    return 0;\n}\n"
    with tempfile.TemporaryDirectory() as tmp:
        c, exe = os.path.join(tmp, "layout.c"), os.path.join(tmp, "layout")
        with open(c, "w") as f:
            f.write(src)
        cflags = subprocess.run(["pkg-config", "--cflags", "hdf5-serial"], capture_output=True, text=True).stdout
        p = subprocess.run([cc, "-std=c11", "-D_GNU_SOURCE", "-Iinclude", *cflags.split(), c, "-o", exe],
                           capture_output=True, text=True)
        if p.returncode:
            print(f"FAIL python_layout_compiles: {p.stderr[-2000:]}")
            return 1
        got = subprocess.run([exe], capture_output=True, text=True, check=True).stdout.split()
    bad = [f"{lab}: ctypes {py}, C {cval}" for (lab, py, _), cval in zip(checks, got) if py != int(cval)]
    if bad:
        print("FAIL python_layout: the ctypes mirrors differ from the headers: " + "; ".join(bad[:20]))
        return 1
    print(f"PASS python_layout ({len(checks)} offsets and sizes of {len(_lib.MIRRORS + _lib.PREFIXES)} structures)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
