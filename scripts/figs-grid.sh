#!/bin/sh
# figs-grid.sh — the data (CSV) and plots (SVG) of Petrò's Figs. 4-5 (2019, §5): how much of the
# measurement noise sigma_r ends up in the estimated stage error, sigma_C/sigma_r, for every method
# (Ye, double shift, least squares on Ye's and on Petrò's views), from the Monte Carlo benchmark
# bench_grid_mc (its tables 1, 3 and 4):
#   Fig. 4:  sigma_C/sigma_r against sigma_r (one chart per N; the paper's is N = 25) and against
#            sigma_G (N = 25, sigma_r = 0.01 um): flat lines, the ratio depends on neither
#   Fig. 5:  sigma_C/sigma_r against N (mean over sigma_r), with least squares' prediction from the
#            estimator covariance (selfcal plan's sigma_c_ratio_rms)
# Writes into out/grid-figs/ (gitignored): bench.md (the benchmark's output), fig4_sr_N*.csv/svg,
# fig4_sg.csv/svg, fig5.csv/svg, and prints the tables.
#
# usage: scripts/figs-grid.sh      FULL=1 for the complete run (200 trials per entry, minutes);
#                                  TRIALS=T to set the trials; SELFCAL=path/to/selfcal and
#                                  BENCH=path/to/bench_grid_mc to use built binaries;
#                                  OUT=DIR to write elsewhere
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
out=${OUT:-$root/out/grid-figs}
mkdir -p "$out"
if [ -z "${SELFCAL:-}" ] || [ -z "${BENCH:-}" ]; then
    cmake -S "$root" -B "$root/build-figs" -G Ninja -DCMAKE_BUILD_TYPE=Release \
        -DSELFCAL_BUILD_TESTS=OFF -DSELFCAL_BUILD_BENCH=ON -DSELFCAL_BUILD_RUNTIME=OFF >/dev/null
    ninja -C "$root/build-figs" selfcal_cli bench_grid_mc >/dev/null
    SELFCAL=${SELFCAL:-$root/build-figs/bin/selfcal}
    BENCH=${BENCH:-$(find "$root/build-figs" -name bench_grid_mc -type f -perm -u+x | head -1)}
fi
S=$SELFCAL
set --
[ "${FULL:-0}" = 1 ] && set -- --full
[ -n "${TRIALS:-}" ] && set -- "$@" --trials "$TRIALS"
"$BENCH" "$@" > "$out/bench.md"

# Table 1: "| N | method | sr=0.001 | sr=0.01 | sr=0.1 | sr=1 | lsq predicted |" -> one CSV per N,
# x = sigma_r, one column per method.
awk -F'|' -v out="$out" '
    /^## 1\./ { t = 1; next } /^## [0-9]/ { t = 0 }
    t && $2 ~ /^ *[0-9]+ *$/ {
        n = $2 + 0; m = $3; gsub(/^ +| +$/, "", m)
        if (!(n in seen)) { seen[n] = 1; ns[++nn] = n }
        k = ++cnt[n]; name[n, k] = m
        for (s = 1; s <= 4; ++s) { v = $(3 + s); gsub(/ /, "", v); val[n, k, s] = v }
        pred[n, k] = $8; gsub(/ /, "", pred[n, k])
    }
    END {
        split("0.001 0.01 0.1 1", sr, " ")
        for (a = 1; a <= nn; ++a) {
            n = ns[a]; f = out "/fig4_sr_N" n ".csv"
            printf "sigma_r_um" > f
            for (k = 1; k <= cnt[n]; ++k) printf ",%s", name[n, k] > f
            printf "\n" > f
            for (s = 1; s <= 4; ++s) {
                printf "%s", sr[s] > f
                for (k = 1; k <= cnt[n]; ++k) printf ",%s", val[n, k, s] > f
                printf "\n" > f
            }
            close(f)
            # predictions for fig. 5
            for (k = 1; k <= cnt[n]; ++k) if (pred[n, k] != "-") print n, name[n, k], pred[n, k] > (out "/pred.txt")
        }
    }' "$out/bench.md"

# Table 3: sigma_G -> fig4_sg.csv (methods as columns)
awk -F'|' '
    /^## 3\./ { t = 1; next } /^## [0-9]/ { t = 0 }
    t && $2 ~ /[a-z]/ && $2 !~ /method/ {
        m = $2; gsub(/^ +| +$/, "", m); names[++k] = m
        for (s = 1; s <= 3; ++s) { v = $(2 + s); gsub(/ /, "", v); val[k, s] = v }
    }
    END {
        printf "sigma_G_um"; for (i = 1; i <= k; ++i) printf ",%s", names[i]; printf "\n"
        split("0.1 1 10", sg, " ")
        for (s = 1; s <= 3; ++s) {
            printf "%s", sg[s]; for (i = 1; i <= k; ++i) printf ",%s", val[i, s]; printf "\n"
        }
    }' "$out/bench.md" > "$out/fig4_sg.csv"

# Table 4: growth with N (mean over sigma_r) -> fig5.csv, plus least squares' predictions
awk -F'|' -v pred="$out/pred.txt" '
    BEGIN { while ((getline line < pred) > 0) { split(line, p, " "); n = p[1]; sub(/^[0-9]+ /, "", line);
                                                v = line; sub(/.* /, "", v); m = line; sub(/ [^ ]*$/, "", m);
                                                pv[n, m] = v } }
    /^## 4\./ { t = 1; next } /^## [0-9]/ { t = 0 }
    t && /^\| method/ { for (i = 3; i <= NF; ++i) if ($i ~ /N=/) { c = $i; gsub(/[^0-9]/, "", c); cols[++nc] = c } }
    t && $2 ~ /[a-z]/ && $2 !~ /method/ {
        m = $2; gsub(/^ +| +$/, "", m); names[++k] = m
        for (i = 1; i <= nc; ++i) { v = $(2 + i); gsub(/ /, "", v); val[k, i] = v }
    }
    END {
        printf "N"; for (i = 1; i <= k; ++i) printf ",%s", names[i]
        for (i = 1; i <= k; ++i) if (names[i] ~ /^lsq/) printf ",%s predicted", names[i]
        printf "\n"
        for (j = 1; j <= nc; ++j) {
            printf "%s", cols[j]; for (i = 1; i <= k; ++i) printf ",%s", val[i, j]
            for (i = 1; i <= k; ++i) if (names[i] ~ /^lsq/) printf ",%s", pv[cols[j], names[i]]
            printf "\n"
        }
    }' "$out/bench.md" > "$out/fig5.csv"
rm -f "$out/pred.txt"

Y="sigma_C / sigma_r"
for f in "$out"/fig4_sr_N*.csv; do
    n=${f##*_N}; n=${n%.csv}
    "$S" plot xy "$f" -o "${f%.csv}.svg" --logx --xlabel "sigma_r (um)" --ylabel "$Y" \
        --title "Fig. 4: sigma_C/sigma_r against the noise sigma_r, N = $n"
done
"$S" plot xy "$out/fig4_sg.csv" -o "$out/fig4_sg.svg" --logx --xlabel "sigma_G (um)" --ylabel "$Y" \
    --title "Fig. 4: sigma_C/sigma_r against the stage error sigma_G, N = 25, sigma_r = 0.01 um"
"$S" plot xy "$out/fig5.csv" -o "$out/fig5.svg" --xlabel "N (marks per side)" --ylabel "$Y" \
    --title "Fig. 5: sigma_C/sigma_r against N (mean over sigma_r), Monte Carlo and prediction"

sed -n '/^## 1\./,/^## 2\./p' "$out/bench.md" | sed '$d'
sed -n '/^## 4\./,$p' "$out/bench.md"
echo "wrote $out/fig4_sr_N*.{csv,svg} fig4_sg.{csv,svg} fig5.{csv,svg} bench.md"
