#!/bin/sh
# Seeds fuzz/corpus/<target> from the shared capture data (the corpus is git-ignored).
# Usage: fuzz/seed.sh DATA_DIR   (e.g. /work/shared/data)
set -eu
data=${1:?usage: seed.sh DATA_DIR}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$here/corpus/c3d_read" "$here/corpus/c3d_roundtrip" "$here/corpus/bvh_read" "$here/corpus/trc_read" "$here/corpus/shard_read"
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
