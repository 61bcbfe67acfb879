# Peak resident memory of `stalm solve` (the defaults) on the first 5 problems of each size of the
# mesh-clutter suite, each in its own process: /usr/bin/time's maximum resident set size.
cd "$CHECKOUT"
export PYTHONPATH="$CHECKOUT"
for i in 000 001 002 003 004 020 021 022 023 024 040 041 042 043 044 060 061 062 063 064; do
  f="$SUITE"/meshscale-$i.yaml
  /usr/bin/time -f "$i %e s %M KB" stalm solve $f --seed 0 --json ./mem-$i.json > /dev/null 2>> ./memory.err
  tail -1 ./memory.err
done
