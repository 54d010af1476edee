#!/usr/bin/env bash
# voxel-cli mesh against VTK's Flying Edges as a user runs them: whole process, cold, one
# run at a time, the two alternating, RUNS runs each (default 7); medians of wall time and
# peak RSS (/usr/bin/time), their ratios, and the meshes' counts (mesh_stats.py).
#   bench/scripts/offline_mesh.sh [NAME...]      (default: every volume below)
# Volumes (made once in /tmp/voxeld_bench/volumes from ../shared/peers and Debian's
# mricron-data; see docs/PERFORMANCE.md "Offline meshing"):
#   terrain  257x129x257 terrain (make_terrain_raw.py), iso 0
#   head     ch2better.nii.gz, a 0.5 mm MRI head (301x370x316 uint8), skin at iso 60
#   noisy    ch2.nii.gz, the 1 mm scan that head was made from, with its scanner noise in
#            the air, resampled to 0.5 mm (362x434x362, samples repeated), iso 24.5: the
#            noise around the head becomes thousands of small surfaces
#   atlas    aal.nii.gz, a brain atlas of 116 labels resampled to 0.5 mm (362x434x362),
#            iso 0.5: large flat regions
# Needs: libvtk9-dev python3-numpy mricron-data (apt-get), the peer built in peers-build/
# (cmake -S ../shared/peers -B peers-build -DCMAKE_BUILD_TYPE=Release && cmake --build
# peers-build), voxel-cli built in build/. THREADS (default 2) for both.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
vol=/tmp/voxeld_bench/volumes out=/tmp/voxeld_bench/offline
mkdir -p "$vol" "$out"
runs="${RUNS:-7}" threads="${THREADS:-2}"
vtk="$root/peers-build/vtk_mesh_ply" cli="$root/build/bin/voxel-cli"
peers="$(cd "$root/../shared/peers" 2>/dev/null && pwd || true)"
templates=/usr/share/mricron/templates
for tool in "$vtk" "$cli" /usr/bin/time; do
  [ -x "$tool" ] || { echo "offline_mesh.sh: $tool is missing (see the header)" >&2; exit 2; }
done

# NAME -> "FILE X Y Z ISO", making FILE when missing.
volume() {
  case "$1" in
    terrain)
      [ -s "$vol/terrain257.raw" ] ||
        /usr/bin/python3 "$peers/make_terrain_raw.py" "$vol/terrain257.raw" 257 129 257 >/dev/null
      echo "$vol/terrain257.raw 257 129 257 0" ;;
    head)
      [ -s "$vol/ch2better.raw" ] ||
        /usr/bin/python3 "$root/bench/scripts/nifti_to_raw.py" "$templates/ch2better.nii.gz" "$vol/ch2better.raw" >/dev/null
      echo "$vol/ch2better.raw 301 370 316 60" ;;
    noisy)
      [ -s "$vol/ch2x2.raw" ] ||
        /usr/bin/python3 "$root/bench/scripts/nifti_to_raw.py" "$templates/ch2.nii.gz" "$vol/ch2x2.raw" 2 >/dev/null
      echo "$vol/ch2x2.raw 362 434 362 24.5" ;;
    atlas)
      [ -s "$vol/aal2x.raw" ] ||
        /usr/bin/python3 "$root/bench/scripts/nifti_to_raw.py" "$templates/aal.nii.gz" "$vol/aal2x.raw" 2 >/dev/null
      echo "$vol/aal2x.raw 362 434 362 0.5" ;;
    *) echo "offline_mesh.sh: unknown volume '$1'" >&2; exit 2 ;;
  esac
}

median() { sort -g | awk '{v[NR] = $1} END {print (NR % 2) ? v[(NR + 1) / 2] : (v[NR / 2] + v[NR / 2 + 1]) / 2}'; }

names=("$@")
[ ${#names[@]} -gt 0 ] || names=(terrain head noisy atlas)
for name in "${names[@]}"; do
  read -r file x y z iso <<<"$(volume "$name")"
  : >"$out/$name.vtk.times"
  : >"$out/$name.cli.times"
  # One run: "WALL_SECONDS PEAK_RSS_KIB" appended to $1 (the wall from the shell's clock:
  # /usr/bin/time's has only 10 ms steps).
  timed() {
    local times="$1" t0 t1
    shift
    t0="$EPOCHREALTIME"
    /usr/bin/time -f "%M" -o "$out/t" "$@" >/dev/null
    t1="$EPOCHREALTIME"
    echo "$(awk -v a="$t0" -v b="$t1" 'BEGIN {printf "%.4f", b - a}') $(cat "$out/t")" >>"$times"
  }
  for r in $(seq "$runs"); do
    timed "$out/$name.vtk.times" "$vtk" "$file" "$x" "$y" "$z" "$iso" "$out/$name.vtk.ply" "$threads"
    timed "$out/$name.cli.times" "$cli" mesh "$file" --dims "$x,$y,$z" --iso "$iso" \
      --threads "$threads" --out "$out/$name.cli.ply"
  done
  vt="$(cut -d' ' -f1 "$out/$name.vtk.times" | median)" vm="$(cut -d' ' -f2 "$out/$name.vtk.times" | median)"
  ct="$(cut -d' ' -f1 "$out/$name.cli.times" | median)" cm="$(cut -d' ' -f2 "$out/$name.cli.times" | median)"
  echo "== $name ($x x $y x $z, iso $iso, $threads threads, median of $runs alternating runs)"
  awk -v vt="$vt" -v vm="$vm" -v ct="$ct" -v cm="$cm" 'BEGIN {
    printf "VTK FE     %.3f s  %6.1f MiB\nvoxel-cli  %.3f s  %6.1f MiB\nratio      %.3f    %.3f\n",
      vt, vm / 1024, ct, cm / 1024, ct / vt, cm / vm }'
  /usr/bin/python3 "$root/bench/scripts/mesh_stats.py" "$out/$name.cli.ply" "$out/$name.vtk.ply"
done
