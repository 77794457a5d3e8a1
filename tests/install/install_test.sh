#!/usr/bin/env bash
# The package as a user meets it (docs/library.md): installs the built project into a temporary
# prefix, configures examples/ as a separate CMake project with find_package(rodfit) against it,
# builds it and runs every example from the repository root (bundled data, no arguments; each
# must exit 0). Also checks that the internal headers under src/ were not installed and that the
# installed public headers compile on their own.
#
# Usage (CTest test `install_examples`): install_test.sh CMAKE BUILD_DIR SOURCE_DIR CXX [CC]
set -euo pipefail
cmake_bin=$1 build_dir=$2 source_dir=$3 cxx=$4 cc=${5:-cc}

work=$(mktemp -d "${build_dir}/install_test.XXXXXX")
trap 'rm -rf "$work"' EXIT
prefix=$work/prefix

"$cmake_bin" --install "$build_dir" --prefix "$prefix" >"$work/install.log"

# Only include/ is the API: exactly its headers and the generated version.h are installed, none
# of the internals under src/ (banded factorisations, stencils, ...).
installed=$(cd "$prefix/include" && find . -type f | sort)
expected=$( (cd "$source_dir/include" && find . -type f; echo ./rodfit/version.h) | sort)
if [ "$installed" != "$expected" ]; then
  echo "installed headers differ from include/ (+ version.h):" >&2
  diff <(echo "$expected") <(echo "$installed") >&2 || true
  exit 1
fi
test -f "$prefix/include/rodfit/version.h"
test -x "$prefix/bin/rodfit"
"$prefix/bin/rodfit" --version
# The commands module is installed in lib/rodfit/ and found there by the installed executable
# (docs/cli.md, "Start-up"): `fit --help` runs in the module.
ls "$prefix"/lib*/rodfit/rodfit-commands.so >/dev/null
"$prefix/bin/rodfit" fit --help >/dev/null

# The installed headers are self-sufficient: one file including all of them compiles against the
# prefix alone (a public header that includes an internal one fails here).
mkdir -p "$work/headers"
(cd "$prefix/include" && find rodfit -name '*.h' | sort | sed 's/.*/#include "&"/') \
  >"$work/headers/all_headers.cc"
cat >"$work/headers/CMakeLists.txt" <<'CMAKE'
cmake_minimum_required(VERSION 3.16)
project(rodfit_headers LANGUAGES CXX)
set(CMAKE_CXX_STANDARD 17)
find_package(rodfit REQUIRED COMPONENTS model solve observe vision fit io)
add_library(all_headers OBJECT all_headers.cc)
target_link_libraries(all_headers PRIVATE rodfit::rodfit)
CMAKE
"$cmake_bin" -S "$work/headers" -B "$work/headers/build" -DCMAKE_CXX_COMPILER="$cxx" \
  -DCMAKE_PREFIX_PATH="$prefix" >"$work/headers.log" 2>&1 &&
  "$cmake_bin" --build "$work/headers/build" >>"$work/headers.log" 2>&1 ||
  { cat "$work/headers.log" >&2; exit 1; }

# The examples, as a separate project.
"$cmake_bin" -S "$source_dir/examples" -B "$work/examples" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_CXX_COMPILER="$cxx" -DCMAKE_C_COMPILER="$cc" -DCMAKE_PREFIX_PATH="$prefix" \
  >"$work/configure.log" ||
  { cat "$work/configure.log" >&2; exit 1; }
"$cmake_bin" --build "$work/examples" -j2 >"$work/build.log" 2>&1 ||
  { cat "$work/build.log" >&2; exit 1; }

cd "$source_dir"
for source in examples/*.cc examples/*.c; do
  example=$(basename "${source%.*}")
  echo "== $example"
  "$work/examples/$example"
done
