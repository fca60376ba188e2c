#!/bin/sh
# GNU time around one process (one MPI rank under mpirun): its report goes to REPORT.rank<R>.
# usage: bench/time_rank.sh REPORT command...
report="$1"; shift
exec /usr/bin/time -v -o "$report.rank${OMPI_COMM_WORLD_RANK:-0}" "$@"
