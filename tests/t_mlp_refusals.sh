#!/usr/bin/env bash
# Malformed network files of `model: mlp` groups (src/io/h5mlp.c, docs/controllers.md): each is refused before any
# result file exists, with exit status 2 from `wavefuel run` and a message naming the scenario line, the network
# file and the dataset; from Python, Scenario.load raises wavefuel.WavefuelError (code 2) with the same message.
# The files are written here from a valid network (wavefuel.export_mlp) and then broken one dataset at a time
# with h5py: wrong shapes, NaN or infinite values, an unknown activation or output kind, missing datasets, an
# input size other than the observation row's 3, a non-positive std, min >= max, a wrong format, not HDF5.
set -u
cd "$(dirname "$0")/.." || exit 1
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
PY=/usr/bin/python3
make --no-print-directory -s python BUILD=build >/dev/null || { echo "FAIL python_build: make python"; exit 1; }
export PYTHONPATH="$PWD/python" WAVEFUEL_LIB="$PWD/lib/libwavefuel.so"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

# case name | the dataset the message must name | text the message must contain (one per line of cases.txt)
$PY - "$tmp" <<'PY' || { ko mlp_cases "could not write the network files"; exit 1; }
import os, sys, h5py, numpy as np, wavefuel as wf
d = sys.argv[1]
rng = np.random.default_rng(3)
good = os.path.join(d, "good.h5")
wf.export_mlp(good, [(rng.normal(size=(8, 3)), rng.normal(size=8)), (rng.normal(size=(8, 8)), rng.normal(size=8)),
                     (rng.normal(size=(1, 8)), rng.normal(size=1))], activations="tanh",
              input_mean=[10, 10, 20], input_std=[5, 5, 10])
cases = []
def case(name, dataset, want, edit):
    p = os.path.join(d, name + ".h5")
    with open(good, "rb") as a, open(p, "wb") as b:
        b.write(a.read())
    with h5py.File(p, "r+") as f:
        edit(f)
    cases.append(f"{name}|{dataset}|{want}")
def put(name, value):
    def edit(f):
        if name in f:
            del f[name]
        f[name] = value
    return edit
def drop(name):
    def edit(f):
        del f[name]
    return edit
def put_at(name, index, value):
    def edit(f):
        x = f[name][()]
        x[index] = value
        del f[name]
        f[name] = x
    return edit
case("nan_weight", "layers/1/weight", "element [2, 5] is nan", put_at("layers/1/weight", (2, 5), np.nan))
case("inf_bias", "layers/0/bias", "element 3 is inf", put_at("layers/0/bias", 3, np.inf))
case("nan_mean", "input/mean", "element 1 is nan", put_at("input/mean", 1, np.nan))
case("inf_scale", "output/scale", "element 0 is -inf", put("output/scale", -np.inf))
case("bad_activation", "layers/1/activation", "is 'sigmoid': expected one of identity, tanh, relu",
     put("layers/1/activation", "sigmoid"))
case("bad_kind", "output/kind", "is 'jerk': expected one of acceleration, speed", put("output/kind", "jerk"))
case("missing_bias", "layers/1/bias", "no dataset", drop("layers/1/bias"))
case("missing_activation", "layers/0/activation", "no dataset", drop("layers/0/activation"))
case("missing_std", "input/std", "no dataset", drop("input/std"))
case("missing_scale", "output/scale", "no dataset", drop("output/scale"))
case("missing_format", "format", "no dataset", drop("format"))
case("bad_format", "format", "is 'wavefuel-mlp 2'", put("format", "wavefuel-mlp 2"))
case("layer_gap", "layers/2", "no group", lambda f: f.move("layers/2", "layers/3"))
case("input_size", "layers/0/weight", "has shape [8, 4]: this layer takes 3 inputs",
     put("layers/0/weight", rng.normal(size=(8, 4))))
case("mean_size", "input/mean", "has 4 values: the observation row has 3", put("input/mean", np.zeros(4)))
case("chain_shape", "layers/1/weight", "has shape [8, 7]: this layer takes 8 inputs",
     put("layers/1/weight", rng.normal(size=(8, 7))))
case("bias_shape", "layers/2/bias", "has 2 values, 'layers/2/weight' has 1 rows", put("layers/2/bias", np.zeros(2)))
case("two_outputs", "layers/2/weight", "has 2 outputs: the last layer gives one command",
     lambda f: (put("layers/2/weight", rng.normal(size=(2, 8)))(f), put("layers/2/bias", np.zeros(2))(f)))
case("weight_rank", "layers/0/weight", "has shape [24], expected a matrix", put("layers/0/weight", np.zeros(24)))
case("int_weight", "layers/0/weight", "is not floating-point", put("layers/0/weight", np.zeros((8, 3), np.int64)))
case("zero_std", "input/std", "element 2 is 0 (must be > 0)", put_at("input/std", 2, 0.0))
case("min_max", "output/min", "3 is not below -3", lambda f: (put("output/min", 3.0)(f), put("output/max", -3.0)(f)))
with open(os.path.join(d, "not_hdf5.h5"), "w") as f:
    f.write("not a network\n")
cases.append("not_hdf5||not an HDF5 file")
cases.append("missing_file||cannot open the network file: No such file or directory")
with open(os.path.join(d, "cases.txt"), "w") as f:
    f.write("\n".join(cases) + "\n")
PY

# The ring of scenarios/sugiyama.yaml with two mlp vehicles whose network is NET.h5 next to the scenario.
scenario() {
  sed -e 's|^name: .*|name: mlp_refusal|' scenarios/sugiyama.yaml >"$tmp/$1.yaml"
  $PY - "$tmp/$1.yaml" "$1.h5" <<'PY'
import sys
p, net = sys.argv[1], sys.argv[2]
s = open(p).read()
i = s.index("  drivers:")
j = s.index("\n", s.index("noise_mps2", i))
s = s[:i] + """  drivers:
    - {name: human, model: idm, count: 20, noise_mps2: 0.3}
    - {name: av, model: mlp, network: %s, count: 2, placement: interleaved}""" % net + s[j:]
open(p, "w").write(s)
PY
}

scenario good
if $BIN run "$tmp/good.yaml" -q -o "$tmp/good_out.h5" && [ -f "$tmp/good_out.h5" ]; then ok mlp_good_network_runs
else ko mlp_good_network_runs "the valid network was not run"; fi

n=0
while IFS='|' read -r name dataset want; do
  [ -n "$name" ] || continue
  n=$((n + 1))
  scenario "$name"
  msg=$($BIN run "$tmp/$name.yaml" -q -o "$tmp/out_$name.h5" 2>&1)
  rc=$?
  if [ $rc -eq 2 ] && [ ! -e "$tmp/out_$name.h5" ] && [ ! -e "$tmp/out_$name.h5.partial" ] &&
     printf '%s' "$msg" | grep -qE "$name.yaml:[0-9]+: " && printf '%s' "$msg" | grep -qF "$tmp/$name.h5" &&
     printf '%s' "$msg" | grep -qF -- "$want" &&
     { [ -z "$dataset" ] || printf '%s' "$msg" | grep -qF "'$dataset'"; }; then
    ok "mlp_refused_cli_$name"
  else
    ko "mlp_refused_cli_$name" "rc=$rc, want '$dataset' and '$want', got: $msg"
  fi
done <"$tmp/cases.txt"
[ "$n" -ge 24 ] || ko mlp_cases "only $n cases"

# From Python: the same refusals as exceptions carrying the same messages (code 2), for the scenario and for the
# network loaded alone.
$PY - "$tmp" <<'PY'
import os, sys, wavefuel as wf
d = sys.argv[1]
for line in open(os.path.join(d, "cases.txt")):
    name, dataset, want = line.rstrip("\n").split("|")
    for what, load in (("scenario", lambda: wf.Scenario.load(os.path.join(d, name + ".yaml"))),
                       ("network", lambda: wf.Network(os.path.join(d, name + ".h5")))):
        try:
            load()
            print(f"FAIL mlp_refused_python_{what}_{name}: no exception")
        except wf.WavefuelError as e:
            good = e.code == 2 and want in str(e) and (not dataset or f"'{dataset}'" in str(e)) and \
                os.path.join(d, name + ".h5") in str(e)
            label = f"mlp_refused_python_{what}_{name}"
            print(("PASS " + label) if good else ("FAIL " + label + ": " + str(e)))
PY

# `network` without model: mlp, and an mlp group without a network, or with a plug-in's `path`.
msg=$($BIN run "$tmp/good.yaml" -q -o "$tmp/x.h5" --set "fleet.drivers[0].network=good.h5" 2>&1); rc=$?
if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF "'network' names a network file and needs model: mlp"; then
  ok mlp_network_needs_model; else ko mlp_network_needs_model "rc=$rc: $msg"; fi
sed -e 's|, network: good.h5||' "$tmp/good.yaml" >"$tmp/nonet.yaml"
msg=$($BIN run "$tmp/nonet.yaml" -q -o "$tmp/x.h5" 2>&1); rc=$?
if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF "network"; then ok mlp_needs_network
else ko mlp_needs_network "rc=$rc: $msg"; fi
msg=$($BIN run "$tmp/good.yaml" -q -o "$tmp/x.h5" --set "fleet.drivers[1].path=x.so" 2>&1); rc=$?
if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF "an mlp group names its network file with 'network'"; then
  ok mlp_path_refused; else ko mlp_path_refused "rc=$rc: $msg"; fi
[ ! -e "$tmp/x.h5" ] || ko mlp_no_output "x.h5 was written"
