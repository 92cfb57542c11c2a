#!/usr/bin/env bash
# Builds the Fast DDS interop client (client.cpp) against Debian's Fast DDS
# 2.9 (libfastrtps-dev, libfastcdr-dev), its types generated from
# ros2_types.idl by Debian's fastddsgen 2.3 (nothing generated is
# committed). Output: $1 (default target/fastdds-check/wmr_fastdds_client);
# each part rebuilt when its source changed.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
OUT="${1:-$HERE/../../../target/fastdds-check/wmr_fastdds_client}"
GEN="$(dirname "$OUT")/gen"
CXX=(g++ -std=c++17 -O1 -w -I"$GEN")
mkdir -p "$GEN"
if ! [ "$GEN/types.o" -nt "$HERE/ros2_types.idl" ] || ! [ "$GEN/types.o" -nt "$0" ]; then
    fastddsgen -replace -d "$GEN" "$HERE/ros2_types.idl" >/dev/null
    "${CXX[@]}" -c -o "$GEN/pubsub.o" "$GEN/ros2_typesPubSubTypes.cxx"
    "${CXX[@]}" -c -o "$GEN/types.o" "$GEN/ros2_types.cxx"
fi
if ! [ "$OUT" -nt "$HERE/client.cpp" ] || ! [ "$OUT" -nt "$GEN/types.o" ]; then
    "${CXX[@]}" -o "$OUT" "$HERE/client.cpp" "$GEN/types.o" "$GEN/pubsub.o" -lfastrtps -lfastcdr -lpthread
fi
