#!/usr/bin/env bash
# Refactoring check: run the same ~110 commands (simulate, grid, profile, lut, export, import,
# plot, report, verify, profile-plan; good input and bad) with two selfcal binaries and compare
# every output file and every stdout/stderr byte for byte, except the creation times that
# tables and reports carry (and the table hashes those times change).
#
#   scripts/compare-outputs.sh OLD/selfcal NEW/selfcal
#
# e.g. OLD built from `git worktree add /tmp/ref main` in Release, NEW from the working tree.
# Exit 0 when the outputs are the same, 1 otherwise (the differences are printed).
set -u
here=$(cd "$(dirname "$0")/.." && pwd)
[ $# -eq 2 ] || { echo "usage: $0 OLD_SELFCAL NEW_SELFCAL" >&2; exit 2; }
old=$(readlink -f "$1"); new=$(readlink -f "$2")
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
export SOURCE_DATE_EPOCH=1700000000 # tables built without --created carry this time
D=$here/tests/data/dabam

suite() {
B=$1
mkdir -p "$2"; cd "$2" || exit 1
k=0
r() { k=$((k+1)); "$B" "$@" > "log.$k" 2>&1; echo "rc=$?" >> "log.$k"; }
r simulate grid --plan double-shift --n 11 --seed 3 --out IN.csv --truth-map T.csv
r grid --method lsq IN.csv --map G.csv
r grid --method double-shift IN.csv --map G2.csv
r simulate profile --n 330 --seed 5 --out P.csv --truth PT.csv
r simulate profile --n 330 --seed 5 --profile $D/dabam-002.dat --out PD.csv --truth PDT.csv
r simulate profile --n 330 --seed 5 --profile $D/dabam-020.dat --out PD2.csv --truth PDT2.csv
r profile --method dft P.csv --out PR.csv
r profile --method lsq P.csv --out PR2.csv
r profile --method dft PD.csv --out PRD.csv
r lut build --map G.csv --profile x:y:PR.csv -o L.tbl
r lut build --map G.csv -o L0.tbl
for f in linuxcnc kmotion siemens-cec klipper marlin reprap; do r export --format $f --map G.csv -o E.$f; done
r export --format beckhoff --map G.csv --axis x -o E.bx
r export --format beckhoff --map G.csv --axis y --interval 0.5 -o E.by
r export --format siemens-cec --map G.csv --profile x:y:PR.csv -o E.sp
r export --format beckhoff --map G.csv --axis x --profile x:y:PR.csv -o E.bc
r export --format beckhoff --map G.csv --axis x --profile x:y:PR.csv --travel -10,400 -o E.bct
r simulate exports IN.csv --dir EX
r import grid --help
for t in L.tbl L0.tbl; do r lut dump $t; r lut info $t; done
r simulate grid --plan ye --n 9 --seed 4 --out S1.csv --truth-map S1T.csv --truth-artifact S1A.csv --truth-summary S1.json --view-sigma-r-um 0.01,0.02,0.03
r simulate grid --plan stitch --n 5 --stage 9,7 --seed 4 --out S2.csv --truth-map S2T.csv
r simulate grid --plan double-shift --n 9 --stage 11,9 --dt-s 1 --drift-um-s 0.001,0.002 --out S3.csv --truth-map S3T.csv
r simulate grid --plan S1.csv --out S4.csv --truth-map S4T.csv --origin-mm 1,2
r simulate grid --plan S1.csv --n 11 --out S5.csv --truth-map S5T.csv
r simulate grid --plan ye --n 9 --view-sigma-r-um 1,2 --out S6.csv --truth-map S6T.csv
r simulate grid --plan stitch --n 9 --out S7.csv --truth-map S7T.csv
r simulate grid --plan ye --n 8 --out S8.csv --truth-map S8T.csv
r simulate grid --plan ye --n 9 --drift-um-s 1,1 --out S9.csv --truth-map S9T.csv
r simulate grid --plan ye --n 9 --bogus 1
r simulate grid --plan ye --n 9 --compensate-with L0.tbl --out S10.csv --truth-map S10T.csv --origin-mm -5,-5 --pitch-mm 1
r export --format beckhoff --map G.csv --axis both -o E.both
r export --format klipper --map G.csv --negate -o E.bad
r export --format marlin --map G.csv --steps-per-mm 80,80 -o E.m2
r plot xy PR.csv -o X1.svg
r plot xy PR.csv --x x_mm --y f_um --y uf_um --logy --title T --xlabel XL --ylabel YL -o X2.svg
r plot xy PR.csv --x nope -o X3.svg
r plot xy PR.csv --logx --logy -o X4.svg
r plot profile PR.csv -o PP.svg
r plot map G.csv -o PM.svg
r report profile P.csv -o RP.html
r report grid IN.csv -o RG.html
r verify --help
r grid --method lsq IN.csv --map GA.csv --artifact A.csv
r lut build --map GA.csv -o LA.tbl
r simulate grid --plan double-shift --n 11 --seed 3 --compensate-with LA.tbl --out V.csv --truth-map VT.csv
r verify V.csv --table LA.tbl --artifact A.csv --tolerance-um 0.5
r verify V.csv --table LA.tbl --artifact A.csv --tolerance-um 0.5 --raw
r verify IN.csv --table LA.tbl --artifact A.csv --tolerance-um 0.01
r verify S1.csv --table LA.tbl --artifact A.csv --tolerance-um 0.01
r report grid IN.csv --verify V.csv --table LA.tbl -o RV.html
r import grid --n 11 --pitch-mm 1 --units um --x-col X --y-col Y --view "rot=0 shift=0,0" EX/view0.csv --view "rot=90 shift=0,0" EX/view1.csv --view "rot=0 shift=2,0" EX/view2.csv --view "rot=0 shift=-3,0 rows=5 cols=5,6" EX/view3.csv -o IMP.csv
r import grid --n 11 --pitch-mm 1 --x-col X --y-col Y --view "rot=0 shift=0,0" EX/view0.csv -o IMP2.csv
r import grid --n 11 --pitch-mm 1 --units um --x-col X --y-col Y --ux-col X --view "rot=0 shift=0,0" EX/view0.csv -o IMP3.csv
r import grid --n 11 --pitch-mm 1 --units um --x-col X --y-col Y --stage 13,13 --origin-mm 1,1 --tolerance-mm 0.2 --view "rot=0 shift=0,0" EX/view0.csv -o IMP4.csv
r plot profile PR.csv --truth PT.csv --compare PR2.csv --label A --compare-label B --title TT -o PP2.svg
r plot profile PR.csv --uncertainty-only -o PP3.svg
r plot profile PR2.csv --truth PT.csv -o PP4.svg
r profile-plan --n 200 --s-mm 1 --sigma-disp-um 0.01 --sigma-angle-urad 0.1 --d-max 12
r profile-plan --n 330 --s-mm 1 --sigma-disp-um 0.01 --sigma-angle-urad 0 --d-max 12 --sort max --top 5
r profile-plan --n 10 --s-mm 1 --sigma-disp-um 0.01 --sigma-angle-urad 0.1 --d-min 5 --d-max 6
r profile-plan --n 10 --s-mm 0 --sigma-disp-um 0.01 --sigma-angle-urad 0.1
r profile-plan --n 10 --s-mm 1 --sigma-disp-um 0 --sigma-angle-urad 0
r profile-plan --n 4 --s-mm 1 --sigma-disp-um 1 --sigma-angle-urad 0 --d-min 1 --d-max 3
r report grid IN.csv --method double-shift --sigma-r-um 0.01 -o RG2.html
r report grid IN.csv --verify V.csv --table LA.tbl --tolerance-um 0.5 --raw -o RV2.html
r report grid IN.csv --verify V.csv -o RV3.html
r simulate exports IN.csv --dir EX2 --units mm --style comma --missing 1,1 --missing 2,3@1 --stray 0 --stray 2 --displace 4,4@0:5,-5 --seed 9
r simulate exports IN.csv --dir EX3 --style tab --missing 99,1
r simulate exports P.csv --dir EX4
r simulate exports S2.csv --dir EX5
r simulate exports IN.csv --dir EX6 --stray 9
r simulate exports IN.csv --dir EX7 --displace 1,1@0:5
r simulate exports IN.csv --dir EX8 --missing 1
r simulate exports IN.csv --dir EX9 --units cm
r simulate profile --n 200 --d1 7 --d2 9 --s-mm 0.5 --amp-um 2 --harmonics 10 --seed 3 --ey-um 1 --ep-urad 2 --u1-um 0.1 --u2-um 0.2 --u3-urad 1 --b0-um 0.5 --out Q1.csv --truth Q1T.csv
r simulate profile --N 100 --noise-free --no-sigma-lines --out Q2.csv --truth Q2T.csv
r simulate profile --n 100 --d1 200 --out Q3.csv --truth Q3T.csv
r simulate profile --n 2 --out Q4.csv --truth Q4T.csv
r simulate profile --n 100 --seed x --out Q5.csv --truth Q5T.csv
r simulate profile --n 100 --amp-um -1 --out Q6.csv --truth Q6T.csv
r simulate profile --n 100 --out
r simulate profile --n 100 --bogus 3
r import profile --spacing-mm 10 EX4/scan1.csv --spacing-mm 11 EX4/scan2.csv --pos-col Position --m1-col SensorA --m2-col SensorB --m3-col Angle -o IP1.csv
r import profile --spacing-mm 10 EX4/scan1.csv --spacing-mm 11 EX4/scan2.csv --pos-col Position --m1-col SensorA --m2-col SensorB --m3-col Angle --pos-units um --disp-units nm --angle-units arcsec --step-mm 0.001 --step-tolerance 0.2 --sigma-disp-um 0.01 --sigma-angle-urad 0.1 -o IP2.csv
r import profile --spacing-mm 10 EX4/scan1.csv --spacing-mm 11 EX4/scan2.csv --pos-col Position --m1-col SensorA --m2-col SensorB --m3-col Angle --sigma-disp-um 0.01 --sigma-angle-urad 0.1 -o IP3.csv
r import profile --spacing-mm 10 EX4/scan1.csv --spacing-mm 11 EX4/scan2.csv --angle-units deg -o IP4.csv
r import profile --spacing-mm 10 EX4/scan1.csv --step-tolerance 0.7 -o IP5.csv
r import profile --spacing-mm 10 EX4/scan1.csv -o IP6.csv
r lut build --map G.csv --profile x:y:PR.csv@5 --profile y:x:PR2.csv --method lsq --sigma 0.01 --created 1700000000 --encoding int32 -o LB1.tbl
r lut dump LB1.tbl
r lut info LB1.tbl
r lut build --map G.csv --encoding int8 -o LB2.tbl
r lut build --map G.csv --created -5 -o LB3.tbl
r verify V.csv --table LA.tbl --artifact A.csv --tolerance-um 0.5 --residuals VR.csv --plot VP.svg --html VH.html
r verify V.csv --table LA.tbl --artifact A.csv --tolerance-um 0.5 --residuals VR2.csv
r grid --method ye S1.csv --map GY.csv --artifact GYA.csv
r grid --method double-shift S3.csv --map GD3.csv
r grid --method double-shift IN.csv --map GD.csv --artifact GDA.csv --summary GD.json
}

suite "$old" "$work/old" >/dev/null 2>&1
suite "$new" "$work/new" >/dev/null 2>&1
cd "$work"
n=$(ls old/log.* | wc -l)
diffs=$(diff -r old new | grep -E '^(diff|Only|Binary|[<>])' | grep -vE 'created|sha256|^diff -r old/(RG|RP|RV|RV2|VH)[0-9]*\.html' || true)
html=$(for f in old/*.html; do diff "$f" "new/${f#old/}" | grep '^[<>]' | grep -vE 'created|sha256'; done)
if [ -z "$diffs$html" ]; then
  echo "compare-outputs: $n commands, the same outputs"
  exit 0
fi
echo "compare-outputs: differences over $n commands:"
echo "$diffs"
echo "$html"
exit 1
