#!/bin/bash
# Which paper-profile switch keeps the tested-scale ANT population on the idle plateau?
mkdir -p "${1:-runs/ablation}" && cd "${1:-runs/ablation}"  # run with the .venv activated
B=ant-evolve
V1=$(python -c "from ant_evolution.profiles import PROFILES as P; print(' '.join(f'{k}={v}' for k,v in P['v1'].items() if P['paper'][k]!=v))")
for seed in 1000 1001 1002; do
  for sw in none $V1; do
    name=${sw%%=*}-s$seed
    [ -f $name/history.csv ] && [ $(wc -l < $name/history.csv) -gt 100 ] && continue
    args="--profile paper"; [ $sw != none ] && args="$args --set $sw"
    nice -n 10 $B $args --out $name --seed $seed --population 100 --scenarios 30 --steps 300 --generations 100 --robots 4 --workers 1 > $name.log 2>&1
  done
  name=v1-s$seed; [ -f $name/history.csv ] || nice -n 10 $B --out $name --seed $seed --population 100 --scenarios 30 --steps 300 --generations 100 --robots 4 --workers 1 > $name.log 2>&1
done
# The paper profile alone on more seeds: which leave the plateau within 100 generations?
for seed in 1003 1004 1005 1006 1007 1008 1009; do
  name=none-s$seed
  [ -f $name/history.csv ] && [ $(wc -l < $name/history.csv) -gt 100 ] && continue
  nice -n 10 $B --profile paper --out $name --seed $seed --population 100 --scenarios 30 --steps 300 --generations 100 --robots 4 --workers 1 > $name.log 2>&1
done
