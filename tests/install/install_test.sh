#!/usr/bin/env bash
# The package as a user meets it (docs/library.md): installs the built project into a temporary
# prefix, configures examples/ as a separate CMake project with find_package(rodfit) against it,
# builds it and runs every example from the repository root (bundled data, no arguments; each
# must exit 0). Also checks that the internal headers under src/ were not installed and that the
# installed public headers compile on their own.
#
# Usage (CTest test `install_examples`): install_test.sh CMAKE BUILD_DIR SOURCE_DIR CXX [CC
#   [PYTHON PYTHON_INSTALL_DIR]] (the last two when the Python package is built)
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

# The shared library (docs/library.md, "Shared library"): librodfit.so.0 with its soname, the C
# API's symbols exported and nothing else, a C program linked against rodfit::rodfit_shared by
# the C linker, and the library found by dlopen as Python's ctypes loads it.
lib=$(ls "$prefix"/lib*/librodfit.so.0)
test -L "$(dirname "$lib")/librodfit.so"
soname=$(objdump -p "$lib" | awk '$1 == "SONAME" {print $2}')
[ "$soname" = "librodfit.so.0" ] || { echo "soname is '$soname', not librodfit.so.0" >&2; exit 1; }
exported=$(nm -D --defined-only "$lib" | awk '$2 ~ /^[TDBR]$/ {print $3}' | sed 's/@.*//' | sort -u)
api=$(grep -o '\brodfit_[a-z_]*(' "$source_dir/include/rodfit/runtime/rodfit_c.h" | tr -d '(' | sort -u)
if [ "$exported" != "$api" ]; then
  echo "librodfit.so exports other symbols than the C API of rodfit_c.h:" >&2
  diff <(echo "$api") <(echo "$exported") >&2 || true
  exit 1
fi
echo "== runtime_c_shared (librodfit.so.0)"
"$work/examples/runtime_c_shared" >/dev/null
# ldd's output taken whole before it is searched: `ldd | grep -q` under pipefail fails at
# random when grep exits at its match before ldd has written everything (ldd killed by SIGPIPE).
loaded=$(ldd "$work/examples/runtime_c_shared")
grep -q "librodfit.so.0 => $prefix" <<<"$loaded" ||
  { echo "runtime_c_shared does not load the installed librodfit.so.0" >&2; exit 1; }
echo "== ctypes"
python3 - "$lib" <<'PY'
import ctypes, sys
lib = ctypes.CDLL(sys.argv[1])
lib.rodfit_status_name.restype = ctypes.c_char_p
assert lib.rodfit_status_name(0) == b"RODFIT_OK", lib.rodfit_status_name(0)
class Options(ctypes.Structure):
    _fields_ = [("mode", ctypes.c_int), ("tool", ctypes.c_int), ("tool_s", ctypes.c_double),
                ("max_iterations", ctypes.c_int), ("gradient_tolerance", ctypes.c_double),
                ("time_budget", ctypes.c_double), ("time_step", ctypes.c_double),
                ("mesh_ring_vertices", ctypes.c_int), ("hold_orientation", ctypes.c_int)]
options = Options()
lib.rodfit_default_options(ctypes.byref(options))
options.tool_s = 0.2
handle = ctypes.c_void_p()
error = ctypes.create_string_buffer(512)
status = lib.rodfit_create(b"data/profiles/suture.json", ctypes.byref(options), None, None, 0,
                           ctypes.byref(handle), error, ctypes.c_size_t(512))
assert status == 0, error.value
assert lib.rodfit_num_vertices(handle) == 51
assert lib.rodfit_step(handle, None) == 0
lib.rodfit_destroy(handle)
print("ctypes: rodfit_create, rodfit_step through", sys.argv[1])
PY

# The Python package (docs/python.md), when built: installed into the prefix's
# lib/pythonX.Y/site-packages, imported from there (not from the build tree), a runtime ticked
# and the runtime example run.
if [ -n "${6:-}" ]; then
  echo "== python package"
  site="$prefix/$7"
  test -f "$site/rodfit/__init__.py" && test -f "$site/rodfit/__init__.pyi"
  PYTHONPATH="$site" "$6" - "$site" <<'PY'
import sys
import rodfit
assert rodfit.__file__.startswith(sys.argv[1]), rodfit.__file__
runtime = rodfit.Runtime("data/profiles/suture.json", mode="dynamic")
force = runtime.step(runtime.tool_position())
assert runtime.status()["ok"] and force.shape == (3,)
print("python: rodfit", rodfit.__version__, "from", rodfit.__file__)
PY
  PYTHONPATH="$site" "$6" examples/python/runtime_loop.py >/dev/null
fi
