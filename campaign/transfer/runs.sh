#!/usr/bin/env bash
# The transfer runs of docs/results.md, "Crossing the reality gap": one queue of runs, each
# resumed where it stopped and skipped once its transfer matrix is written.
#   bash campaign/transfer/runs.sh QUEUE      (QUEUE: a to e; run two queues on two cores)
set -euo pipefail
cd "$(dirname "$0")/../.."
common=(--population 40 --scenarios 12 --generations 300 --checkpoint-every 5 --quiet)
start=(--start genomes/best.json)
run() {  # run NAME SEED ARGS...
  local out="campaign/transfer/$1" seed="$2"
  shift 2
  [[ -f "$out/transfer.json" ]] && return 0
  local resume=()
  # a run stopped at a session's end: its checkpoint was committed compressed
  [[ -f "$out/checkpoint.json.gz" && ! -f "$out/checkpoint.json" ]] && gunzip -k "$out/checkpoint.json.gz"
  [[ -f "$out/checkpoint.json" ]] && resume=(--resume)
  nice -n 10 ant-evolve --out "$out" --seed "$seed" "${common[@]}" "$@" "${resume[@]}"
  rm -f "$out/checkpoint.json.gz"  # finished: the matrix is written, no checkpoint is kept
}
case "${1:?queue a, b, c, d or e}" in
  a)
    for s in 1 2 3; do run "finetune-dome-rand-$s" "$s" --soil physical:dome --randomise "${start[@]}"; done
    for s in 1 2 3; do run "scratch-dome-rand-$s" "$s" --soil physical:dome --randomise; done
    ;;
  b)
    for s in 1 2 3; do
      run "combined-progress-rand-$s" "$s" --also-soil physical:dome --combine progress --randomise "${start[@]}"
    done
    ;;
  c)
    for s in 1 2 3; do
      run "combined-progress-$s" "$s" --also-soil physical:dome --combine progress "${start[@]}"
    done
    ;;
  d)
    for s in 2 3; do run "finetune-dome-$s" "$s" --soil physical:dome "${start[@]}"; done
    ;;
  e)
    for s in 1 2 3; do
      run "floor-dome-$s" "$s" --also-soil physical:dome --combine floor "${start[@]}"
    done
    ;;
esac
