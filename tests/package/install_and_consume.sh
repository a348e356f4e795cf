#!/usr/bin/env bash
# Must-show 4 of the Python issue: the installed tree works from outside the build. Installs the
# build into a fresh prefix, then from a fresh directory: imports the Python package and fits with
# it; configures, builds and runs tests/package/consumer with find_package(stampede); compiles the
# same program with pkg-config's flags alone.
# usage: install_and_consume.sh BUILD_DIR PYTHON
set -euo pipefail
build=$(cd "$1" && pwd)
python=$2
src=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/stampede_package_XXXXXX")
trap 'rm -rf "$work"' EXIT
prefix="$work/prefix"
cmake --install "$build" --prefix "$prefix" > "$work/install.log"

site=$(find "$prefix" -type d -name stampede -path "*-packages/*" | head -1)
[[ -n $site ]] || { echo "no Python package under $prefix"; cat "$work/install.log"; exit 1; }
mkdir "$work/fresh" && cd "$work/fresh"
PYTHONPATH=$(dirname "$site") "$python" -c '
import stampede, numpy as np
assert stampede.__file__.startswith("'"$prefix"'"), stampede.__file__
sim = stampede.simulate_great08(noise_free=True, grid=2)
rows = stampede.fit_stamps(sim["stamps"], options={"renderer": "exact", "psf_e2": 0.05})
d = np.max(np.abs(rows["e1"] - sim["truth"]["e1_obs"]))
assert d < 1e-4, d
print("python: stampede", stampede.__version__, "from", stampede.__file__, "max |de1| = %.2e" % d)
'

cmake -S "$src/consumer" -B "$work/consumer" -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_BUILD_TYPE=Release > "$work/consumer.log"
cmake --build "$work/consumer" -j2 >> "$work/consumer.log" || { cat "$work/consumer.log"; exit 1; }
"$work/consumer/consumer"

pc=$(find "$prefix" -name stampede.pc | head -1)
flags=$(PKG_CONFIG_PATH=$(dirname "$pc") pkg-config --cflags --libs stampede)
g++ -O2 "$src/consumer/main.cpp" -o "$work/pkgconfig_consumer" $flags
"$work/pkgconfig_consumer" > /dev/null
echo "pkg-config: built and ran with: $flags"
