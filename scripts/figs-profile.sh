#!/bin/sh
# figs-profile.sh — the data (CSV) and plots (SVG) of Ding et al.'s Figs. 3-5: uncertainty along
# the profile for the paper's set-up (N = 330, s = 1 mm, d = 10/11 and 3/11, sigma_disp = 10 nm,
# sigma_angle = 1 nm/mm = 1 urad).
#   Fig. 3: DFT method, d = 10/11 and 3/11     Fig. 4: least squares, d = 10/11 and 3/11
#   Fig. 5: DFT vs least squares, d = 10/11
# Each curve is the analytic prediction; a seeded Monte Carlo run (MC trials, default 5000) checks
# it. Writes into out/profile-figs/ (gitignored) and prints the checks.
#
# usage: scripts/figs-profile.sh            (SELFCAL=path/to/selfcal to use a built binary;
#                                             MC=K for the number of Monte Carlo trials)
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
out=$root/out/profile-figs
mkdir -p "$out"
if [ -z "${SELFCAL:-}" ]; then
    cmake -S "$root" -B "$root/build-figs" -G Ninja -DCMAKE_BUILD_TYPE=Release \
        -DSELFCAL_BUILD_TESTS=OFF -DSELFCAL_BUILD_BENCH=OFF -DSELFCAL_BUILD_RUNTIME=OFF >/dev/null
    ninja -C "$root/build-figs" selfcal_cli >/dev/null
    SELFCAL=$root/build-figs/bin/selfcal
fi
MC=${MC:-5000}
S=$SELFCAL

for pair in 10_11 3_11; do
    d1=${pair%_*}
    d2=${pair#*_}
    "$S" simulate profile --n 330 --s-mm 1 --d1 "$d1" --d2 "$d2" --sigma-disp-um 0.01 \
        --sigma-angle-urad 1 --seed 2011 --out "$out/in_$pair.csv" --truth "$out/truth_$pair.csv" >/dev/null
    for m in dft lsq; do
        "$S" profile --method $m "$out/in_$pair.csv" --out "$out/${m}_$pair.csv" --quiet
        "$S" profile --method $m "$out/in_$pair.csv" --out "$out/${m}_${pair}_mc.csv" --mc "$MC" --seed 7 --quiet
    done
done

# fig CSV: x_mm, then u(f) in nm of each curve, predicted and Monte Carlo
figcsv() { # name a b
    paste -d, "$out/$2.csv" "$out/$2_mc.csv" "$out/$3.csv" "$out/$3_mc.csv" | awk -F, -v a="$2" -v b="$3" '
        NR == 1 { printf "x_mm,u_%s_nm,u_%s_mc_nm,u_%s_nm,u_%s_mc_nm\n", a, a, b, b; next }
        { printf "%s,%.4f,%.4f,%.4f,%.4f\n", $2, 1e3 * $4, 1e3 * $9, 1e3 * $14, 1e3 * $19 }' > "$out/$1.csv"
}
figcsv fig3 dft_10_11 dft_3_11
figcsv fig4 lsq_10_11 lsq_3_11
figcsv fig5 dft_10_11 lsq_10_11

"$S" plot profile "$out/dft_10_11.csv" --compare "$out/dft_3_11.csv" -o "$out/fig3.svg" --uncertainty-only \
    --label "d1 = 10, d2 = 11" --compare-label "d1 = 3, d2 = 11" \
    --title "Fig. 3: DFT method, N = 330, s = 1 mm, 10 nm / 1 nm/mm noise"
"$S" plot profile "$out/lsq_10_11.csv" --compare "$out/lsq_3_11.csv" -o "$out/fig4.svg" --uncertainty-only \
    --label "d1 = 10, d2 = 11" --compare-label "d1 = 3, d2 = 11" \
    --title "Fig. 4: least squares, N = 330, s = 1 mm, 10 nm / 1 nm/mm noise"
"$S" plot profile "$out/dft_10_11.csv" --compare "$out/lsq_10_11.csv" -o "$out/fig5.svg" --uncertainty-only \
    --label "DFT" --compare-label "least squares" \
    --title "Fig. 5: DFT vs least squares, d = 10/11, N = 330"
# and the Monte Carlo check as plots (prediction vs MC)
for c in dft_10_11 dft_3_11 lsq_10_11 lsq_3_11; do
    "$S" plot profile "$out/$c.csv" --compare "$out/${c}_mc.csv" -o "$out/check_$c.svg" --uncertainty-only \
        --label "predicted" --compare-label "Monte Carlo ($MC trials)" --title "$c: predicted vs Monte Carlo"
done

echo "curve       u(mid) nm  u(edge) nm  RMS nm   MC/pred RMS  worst point |MC/pred-1|"
for c in dft_10_11 dft_3_11 lsq_10_11 lsq_3_11; do
    paste -d, "$out/$c.csv" "$out/${c}_mc.csv" | awk -F, -v c="$c" '
        NR > 1 { u = $4; v = $9; s1 += u * u; s2 += v * v; k++; r = v / u - 1; if (r < 0) r = -r;
                 if (r > w) w = r; if ($1 == 165) mid = u; if ($1 == 0) e = u }
        END { printf "%-10s %9.2f %11.2f %8.2f %12.4f %12.3f\n", c, 1e3 * mid, 1e3 * e,
                     1e3 * sqrt(s1 / k), sqrt(s2 / s1), w }'
done
echo "wrote $out/fig3.{csv,svg} fig4.{csv,svg} fig5.{csv,svg} check_*.svg"
