#!/usr/bin/env bash
# Plug-in controllers end to end (`model: plugin`, src/models/cf/plugin.c): the example plugin run through
# `wavefuel run` from a scenario that names it by a relative path gives the same per-vehicle results, bit for
# bit, as the built-in follower_stopper, and records its own name; broken plugins (compiled here from small
# sources) are refused before any result file exists, with exit status 2 and a message that names the
# scenario line and the cause: missing file, no entry point, another ABI version, a refusing entry point, an
# invalid parameter table, inconsistent state functions, a parameter the plugin does not declare, and a
# `path` given to a built-in model.
set -u
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
BUILD=${BUILD:-build}
CC=${CC:-cc}
PY=/usr/bin/python3
ROOT=$(pwd)
SO="$ROOT/$BUILD/plugins/follower_stopper_plugin.so"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }

if [ ! -f "$SO" ]; then ko plugin_built "$SO missing: run make tests"; exit 1; fi

# The scenario with its AV group switched to the plugin, named relative to the scenario's directory.
mkdir -p "$tmp/scen" "$tmp/lib"
cp "$SO" "$tmp/lib/fs.so"
sed -e 's|model: follower_stopper|model: plugin\n      path: ../lib/fs.so|' scenarios/sugiyama_followerstopper.yaml \
  >"$tmp/scen/plugin.yaml"
if ! grep -q 'path: ../lib/fs.so' "$tmp/scen/plugin.yaml"; then ko plugin_scenario "could not write the scenario"; exit 1; fi

$BIN run scenarios/sugiyama_followerstopper.yaml -q -o "$tmp/builtin.h5" &&
  $BIN run "$tmp/scen/plugin.yaml" -q -o "$tmp/plugin.h5"
rc=$?
if [ $rc -eq 0 ] && $PY - "$tmp/builtin.h5" "$tmp/plugin.h5" <<'PY'
import sys, h5py, numpy as np
a, b = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
assert [m.decode() for m in b["drivers/model"][:]] == ["idm", "follower_stopper_plugin"], b["drivers/model"][:]
names = []
a.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
compared = 0
for n in names:
    if not (n.startswith("vehicles/") or n.startswith("trajectories/") or n.startswith("timeseries/")
            or n.startswith("summary/")):
        continue
    x, y = np.asarray(a[n][()]), np.asarray(b[n][()])
    if x.dtype.kind not in "fiub":
        continue
    assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), f"{n} differs"
    compared += 1
assert compared > 20, compared
PY
then ok plugin_same_bits_as_builtin; else ko plugin_same_bits_as_builtin "rc=$rc"; fi

# Broken plugins. Each source is compiled against the real header; $1 name, $2 C body after the include.
build_plugin() {
  printf '#include "wavefuel/cf_plugin.h"\n%s\n' "$2" >"$tmp/$1.c"
  $CC -std=c11 -fPIC -shared -Iinclude "$tmp/$1.c" -o "$tmp/lib/$1.so" 2>"$tmp/$1.cc.log"
}
# expect_refusal NAME LIB WANT [--set ...]: the plugin scenario with the AV group's path set to lib/LIB.so;
# the message must name the scenario file and line.
expect_refusal() {
  local name=$1 lib=$2 want=$3 msg rc; shift 3
  sed -e "s|path: ../lib/fs.so|path: ../lib/$lib.so|" "$tmp/scen/plugin.yaml" >"$tmp/scen/$name.yaml"
  msg=$($BIN run "$tmp/scen/$name.yaml" -q -o "$tmp/bad_$name.h5" "$@" 2>&1)
  rc=$?
  if [ $rc -eq 2 ] && [ ! -e "$tmp/bad_$name.h5" ] && [ ! -e "$tmp/bad_$name.h5.partial" ] &&
     printf '%s' "$msg" | grep -qF -- "$want" && printf '%s' "$msg" | grep -qE "$name.yaml:[0-9]+: "; then
    ok "plugin_refused_$name"
  else
    ko "plugin_refused_$name" "rc=$rc, want '$want', got: $msg"
  fi
}

COMMON='
static double acc0(const void *p, const void *s, double g, double v, double vl) { (void)p; (void)s; (void)g; (void)v; (void)vl; return 0.0; }
static const WfCfPluginParam one[] = {{"U_mps", 1.0, 0.0, 2.0, "m/s", "a speed"}};'

expect_refusal missing missing "cannot load plugin"

build_plugin no_entry 'int not_the_entry(void); int not_the_entry(void) { return 0; }'
expect_refusal no_entry no_entry "does not export wf_cf_plugin_entry"

build_plugin old_abi "$COMMON
static const WfCfPlugin d = {WF_CF_PLUGIN_ABI_VERSION + 1, \"old\", \"doc\", one, 1, 0, acc0, 0, 0, 0};
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e);
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e) { (void)h; (void)e; *o = &d; return 0; }"
expect_refusal old_abi old_abi "built for controller ABI version 2, this wavefuel has version 1"

build_plugin refuses "
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e);
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e) { (void)o; return h->error(e, 2, \"needs a licence file\"); }"
expect_refusal refuses refuses "refused to load: needs a licence file"

build_plugin bad_default "
static double acc0(const void *p, const void *s, double g, double v, double vl) { (void)p; (void)s; (void)g; (void)v; (void)vl; return 0.0; }
static const WfCfPluginParam one[] = {{\"U_mps\", 5.0, 0.0, 2.0, \"m/s\", \"a speed\"}};
static const WfCfPlugin d = {WF_CF_PLUGIN_ABI_VERSION, \"bad\", \"doc\", one, 1, 0, acc0, 0, 0, 0};
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e);
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e) { (void)h; (void)e; *o = &d; return 0; }"
expect_refusal bad_default bad_default "parameter 'U_mps' needs finite min <= default <= max"

build_plugin half_state "$COMMON
static void init(const void *p, void *s, double g, double v, double vl) { (void)p; (void)s; (void)g; (void)v; (void)vl; }
static const WfCfPlugin d = {WF_CF_PLUGIN_ABI_VERSION, \"half\", \"doc\", one, 1, 0, acc0, 16, init, 0};
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e);
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e) { (void)h; (void)e; *o = &d; return 0; }"
expect_refusal half_state half_state "state_size 16 needs both init_state and update_state"

# A valid plugin whose table lacks a key the scenario sets: the usual unknown-key error with a suggestion.
build_plugin small "$COMMON
static const WfCfPlugin d = {WF_CF_PLUGIN_ABI_VERSION, \"small\", \"doc\", one, 1, 0, acc0, 0, 0, 0};
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e);
int wf_cf_plugin_entry(const WfCfPluginHost *h, const WfCfPlugin **o, struct WfError *e) { (void)h; (void)e; *o = &d; return 0; }"
expect_refusal unknown_param small "unknown key 'fleet.drivers[1].params.k_per_s'" --set "fleet.drivers[1].params.U_mps=1.5"
# ... and its range check from the plugin's own table.
expect_refusal param_range small "params.U_mps: expected a number in [0, 2] m/s (got '2.5')"

msg=$($BIN run scenarios/sugiyama_followerstopper.yaml -q -o "$tmp/p.h5" --set "fleet.drivers[1].path=x.so" 2>&1)
rc=$?
if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF "needs model: plugin"; then ok path_needs_plugin_model
else ko path_needs_plugin_model "rc=$rc: $msg"; fi

msg=$($BIN run scenarios/sugiyama_followerstopper.yaml -q -o "$tmp/p.h5" --set "fleet.drivers[1].model=plugn" 2>&1)
rc=$?
if [ $rc -eq 2 ] && printf '%s' "$msg" | grep -qF "or 'plugin' with 'path"; then ok unknown_model_mentions_plugin
else ko unknown_model_mentions_plugin "rc=$rc: $msg"; fi
