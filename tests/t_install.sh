#!/usr/bin/env bash
# `make install PREFIX=DIR` into a temporary prefix, then the installed program run from another directory with no
# WAVEFUEL_* variable: it finds its classes and drive cycles under PREFIX/share/wavefuel, writes the default
# output/NAME.h5 in the working directory, gives the repository binary's numbers, prints sweep commands that run as
# printed; a program compiled with `pkg-config wavefuel` against the installed headers and library evaluates a class
# as the installed `wavefuel energy` does. Prints "PASS name" / "FAIL name: why".
set -u
cd "$(dirname "$0")/.." || exit 1
REPO=$PWD
BIN=${WAVEFUEL_BIN:-bin/wavefuel}
case "$BIN" in /*) ;; *) BIN="$REPO/$BIN" ;; esac
DATA=${WAVEFUEL_DATA:-$REPO/../shared/data}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
ok() { echo "PASS $1"; }
ko() { echo "FAIL $1: $2"; }
P=$tmp/prefix

# The default build is installed (make builds it if needed), whatever build is under test: `make install` with the
# sanitizer builds' objects (BUILD=build-san, build-tsan from tests/run.sh) would relink them without their
# sanitizer flags and remove the binary under test.
if make --no-print-directory install PREFIX="$P" DATA="$DATA" BUILD=build BIN="$REPO/bin/wavefuel" \
     LIBA="$REPO/lib/libwavefuel.a" >"$tmp/install.log" 2>&1; then
  ok make_install; else ko make_install "$(tail -5 "$tmp/install.log")"; exit 0; fi

# Every file the install promises, against the repository's lists.
missing=""
for f in bin/wavefuel lib/libwavefuel.a lib/pkgconfig/wavefuel.pc; do [ -f "$P/$f" ] || missing="$missing $f"; done
for h in include/wavefuel/*.h; do cmp -s "$h" "$P/$h" || missing="$missing $h"; done
for v in vehicles/*.yaml; do cmp -s "$v" "$P/share/wavefuel/$v" || missing="$missing $v"; done
for s in scenarios/*.yaml scenarios/data/*; do cmp -s "$s" "$P/share/wavefuel/$s" || missing="$missing $s"; done
if [ -d "$DATA/cycles" ]; then
  for c in "$DATA"/cycles/*.csv; do cmp -s "$c" "$P/share/wavefuel/data/cycles/$(basename "$c")" || missing="$missing $c"; done
fi
if [ -z "$missing" ] && [ -x "$P/bin/wavefuel" ]; then ok installed_files; else ko installed_files "missing or different:$missing"; fi

# From another directory, without the variables that point at the repository.
mkdir "$tmp/elsewhere" && cd "$tmp/elsewhere" || exit 1
W() { env -u WAVEFUEL_VEHICLES -u WAVEFUEL_DATA "$P/bin/wavefuel" "$@"; }
list=$(W energy --list); n=$(echo "$list" | grep -c "$P/share/wavefuel/vehicles/")
if [ "$n" -eq "$(ls "$REPO"/vehicles/*.yaml | wc -l)" ]; then ok installed_finds_its_classes
else ko installed_finds_its_classes "$n classes found: $list"; fi

if [ -d "$DATA/cycles" ]; then
  got=$(W cycle --class midsize_suv udds | grep '^circles_polynomial')
  want=$(cd "$REPO" && "$BIN" cycle --class midsize_suv --cycles "$DATA" udds | grep '^circles_polynomial')
  if [ -n "$got" ] && [ "$got" = "$want" ]; then ok installed_finds_its_cycles
  else ko installed_finds_its_cycles "got '$got' want '$want'"; fi
else
  echo "PASS installed_finds_its_cycles (skipped: no $DATA/cycles to install)"
fi

# The default output: output/NAME.h5 in the working directory (created), the repository binary's numbers.
got=$(W run "$P/share/wavefuel/scenarios/sugiyama.yaml" | grep -v '^wavefuel run:')
want=$(cd "$REPO" && "$BIN" run scenarios/sugiyama.yaml -o "$tmp/ref.h5" | grep -v '^wavefuel run:' |
       sed "s|^result: .*|result: output/sugiyama.h5|")
if [ -f output/sugiyama.h5 ] && [ "$got" = "$want" ]; then ok installed_run_default_output_here
else ko installed_run_default_output_here "$(ls) / got: $got / want: $want"; fi

# A scenario in another directory naming its class by a file name: resolved next to the scenario, not here.
mkdir -p "$tmp/proj"
cp "$REPO/vehicles/midsize_sedan.yaml" "$tmp/proj/my_sedan.yaml"
sed 's|class: midsize_sedan|class: my_sedan.yaml|' "$REPO/scenarios/sugiyama.yaml" > "$tmp/proj/s.yaml"
if grep -q 'class: my_sedan.yaml' "$tmp/proj/s.yaml" && W run "$tmp/proj/s.yaml" -o mine.h5 -q && [ -f mine.h5 ]; then
  ok class_file_relative_to_scenario; else ko class_file_relative_to_scenario "rc=$?"; fi

# Commands the sweep prints run as printed (here, from this directory).
cmd=$(W sweep "$P/share/wavefuel/scenarios/sweep_penetration.yaml" --list | sed -n 3p)
case "$cmd" in "$P/bin/wavefuel run "*) first=ok ;; *) first="starts with '${cmd%% *}'" ;; esac
if [ "$first" = ok ] && sh -c "$cmd -q -o printed.h5" && [ -f printed.h5 ]; then ok sweep_list_runs_as_printed
else ko sweep_list_runs_as_printed "$first: $cmd"; fi

# A program built with pkg-config against the installed library: same fuel rate as the installed command.
cat > use.c <<'C'
#include <stdio.h>
#include "wavefuel/vehicle.h"
int main(int argc, char **argv)
{
    WfError err = {0};
    WfVehicleClass vc;
    if (argc != 2 || wf_vehicle_search_path_set(argv[1], &err) || wf_vehicle_find("midsize_suv", &vc, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    double v = 20, a = 0.5, th = 0.01, f;
    wf_vehicle_fuel(&vc, 1, &v, &a, &th, 0, &f, NULL);
    printf("%.17g\n", f);
    wf_vehicle_free(&vc);
    return 0;
}
C
if PKG_CONFIG_PATH="$P/lib/pkgconfig" cc -std=c11 use.c $(PKG_CONFIG_PATH="$P/lib/pkgconfig" pkg-config --cflags wavefuel) \
     $(PKG_CONFIG_PATH="$P/lib/pkgconfig" pkg-config --libs wavefuel) -o use 2>cc.log; then
  got=$(./use "$P/share/wavefuel/vehicles")
  want=$(printf 'v,a,theta\n20,0.5,0.01\n' | W energy --class midsize_suv | sed -n 2p | cut -d, -f4)
  if [ -n "$got" ] && [ "$got" = "$want" ]; then ok pkg_config_program_links_and_agrees
  else ko pkg_config_program_links_and_agrees "got $got want $want"; fi
else
  ko pkg_config_program_links_and_agrees "$(head -5 cc.log)"
fi
