#!/bin/sh
# Seeds fuzz/corpus/<target> from the shared capture data (the corpus is git-ignored).
# Usage: fuzz/seed.sh DATA_DIR   (e.g. /work/shared/data)
set -eu
data=${1:?usage: seed.sh DATA_DIR}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$here/corpus/c3d_read" "$here/corpus/c3d_roundtrip" "$here/corpus/bvh_read" "$here/corpus/trc_read" "$here/corpus/shard_read" \
    "$here/corpus/csv_read" "$here/corpus/asf_amc_read" "$here/corpus/layout_read" "$here/corpus/gap_stats_read"
# Layouts and gap statistics: the ones shipped with locap-synth.
cp "$here"/../crates/synth/layouts/*.toml "$here/corpus/layout_read/"
cp "$here"/../crates/synth/data/*.json "$here/corpus/gap_stats_read/"
find "$data" -name '*gap*.json' -exec cp {} "$here/corpus/gap_stats_read/" \;
# C3D files are cut to their first 64 KiB: header and parameter section whole, a few frames
# of data (the reader reads the complete frames of a truncated file). Whole files of several
# MiB would slow libFuzzer down far more than they add coverage.
find "$data" -name '*.c3d' | while read -r f; do
    n=$(basename "$f" .c3d)_$(echo "$f" | cksum | cut -d' ' -f1)
    head -c 65536 "$f" > "$here/corpus/c3d_read/$n.c3d"
    cp "$here/corpus/c3d_read/$n.c3d" "$here/corpus/c3d_roundtrip/$n.c3d"
done
# Text files: the first 200 lines keep every header form and some frames, and runs fast.
find "$data" -name '*.bvh' | while read -r f; do
    head -n 200 "$f" > "$here/corpus/bvh_read/$(basename "$f")"
done
find "$data" -name '*.trc' | while read -r f; do
    head -n 200 "$f" > "$here/corpus/trc_read/$(basename "$f")"
done
# CSV: the shared data has no marker tables, so the seeds are written here in the layout
# `locap_io::csv::write_csv` produces (quoted names, missing samples, a fractional rate).
printf 'frame,time_s,Male:LFWT_x_mm,Male:LFWT_y_mm,Male:LFWT_z_mm,RBAC_x_mm,RBAC_y_mm,RBAC_z_mm\n1,0,12.3456,-7.8900,1001.0000,,,\n2,0.008333333333333333,12.4,-7.9,1001.5,1.0,2.0,3.0\n3,0.016666666666666666,,,,1.1,2.1,3.1\n' \
    > "$here/corpus/csv_read/two_markers.csv"
printf 'frame,time_s,"a,b_x_mm","a,b_y_mm","a,b_z_mm"\r\n10,0.09,1,2,3\r\n11,0.1,4,5,6\r\n' > "$here/corpus/csv_read/quoted_crlf.csv"
# ASF/AMC: a skeleton, a NUL byte, then the start of one of its motions (the target splits
# the input there). The ASF is kept whole (its bones must all be there), the AMC cut to 3
# frames' worth of lines.
find "$data" -name '*.asf' | while read -r asf; do
    amc=$(find "$(dirname "$asf")" -name '*.amc' | head -n 1)
    out="$here/corpus/asf_amc_read/$(basename "$asf" .asf).bin"
    { cat "$asf"; printf '\000'; [ -n "$amc" ] && head -n 100 "$amc"; } > "$out"
done
# Training shards: one synthesized from a CMU BVH take by locap itself (needs a built locap),
# cut to its header and a few frames.
locap="$here/../target/release/locap"
if [ -x "$locap" ] && [ -d "$data/cmu-bvh" ]; then
    tmp=$(mktemp -d)
    bvh=$(find "$data/cmu-bvh" -name '*.bvh' | head -n 1)
    "$locap" synth --motion "$bvh" -o "$tmp" --format shard --seed 1 >/dev/null
    for f in "$tmp"/*.shard; do head -c 8192 "$f" > "$here/corpus/shard_read/$(basename "$f")"; done
    rm -rf "$tmp"
fi
