#!/bin/sh
# Regenerates the recordings of the bundled example study (run from this folder).
# Each participant: a simulated person with known (θ*, β*) under the maxent-relative model
# (every one of them reaches a goal), driven and recorded at 10 Hz with 3 cm of noise,
# pauses, and, for P04, one 3-second gap. The truths are in truth.csv.
set -e
rec() { expertise-irl simulate-recordings "$@" --model maxent-relative --max-steps 3000 --force; }
rec spec-a.txt --theta 0.5,0.2,0.3   --beta 0.1 --seed 1  --out recordings/P01.csv
rec spec-a.txt --theta 0.4,0.4,0.2   --beta 0.3 --seed 2  --out recordings/P02.csv
rec spec-b.txt --theta 0.6,0.1,0.3   --beta 0.5 --seed 3  --out recordings/P03.csv
rec spec-b.txt --theta 0.5,0,0.5     --beta 0.8 --seed 4  --out recordings/P04.csv --gaps 1
rec spec-c.txt --theta 0.7,0.3,0     --beta 1.2 --seed 5  --out recordings/P05.csv
rec spec-c.txt --theta 0.4,0.2,0.4   --beta 2.0 --seed 6  --out recordings/P06.csv
rec spec-a.txt --theta 0.5,0.25,0.25 --beta 0.2 --seed 7  --out recordings/P07-a.csv
rec spec-c.txt --theta 0.5,0.25,0.25 --beta 0.2 --seed 17 --out recordings/P07-c.csv
rec spec-b.txt --theta 0.6,0.2,0.2   --beta 2.5 --seed 9  --out recordings/P08.csv
