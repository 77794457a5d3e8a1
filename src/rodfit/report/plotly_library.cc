// plotly_library.h: the reports' plotly.js, found once per process.
#include "rodfit/report/plotly_library.h"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#ifndef RODFIT_PLOTLY_JS_PATH
#define RODFIT_PLOTLY_JS_PATH ""
#endif

namespace rodfit {
namespace {

// A plotly.js bundle is ~1.7 MB minified (gl3d) or ~9 MB (the full, unminified bundle); a file
// far larger is not one, and is not inlined into every report.
constexpr std::streamoff kMaxLibraryBytes = 64 << 20;

bool ReadLibrary(const std::string& path, std::string* text) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size <= 0 || size > kMaxLibraryBytes) return false;
  in.seekg(0);
  std::ostringstream out;
  out << in.rdbuf();
  *text = out.str();
  // The page's check: a plotly.js bundle defines the Plotly global.
  return text->find("Plotly") != std::string::npos;
}

PlotlyLibrary Find() {
  PlotlyLibrary lib;
  std::vector<std::string> tried;
  if (const char* env = std::getenv("RODFIT_PLOTLY_JS"); env && *env) {
    // Named by the user: used, or said why not, never silently replaced by another file.
    if (ReadLibrary(env, &lib.script)) {
      lib.path = env;
    } else {
      lib.script.clear();
      lib.missing = std::string("RODFIT_PLOTLY_JS=") + env +
                    " is not a readable plotly.js file: the report has no 3-D view";
    }
    return lib;
  }
  // An installed rodfit (cmake --install, any prefix) has its copy in PREFIX/share/rodfit,
  // beside PREFIX/bin where the running executable is.
  std::string beside_executable;
  {
    std::error_code ec;
    const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
    if (!ec)
      beside_executable =
          (exe.parent_path().parent_path() / "share/rodfit/plotly-gl3d.min.js").string();
  }
  for (const std::string& path : {std::string(RODFIT_PLOTLY_JS_PATH), beside_executable,
                                  std::string(RODFIT_INSTALL_PREFIX "/share/rodfit/plotly-gl3d.min.js")}) {
    if (path.empty() || std::find(tried.begin(), tried.end(), path) != tried.end()) continue;
    tried.push_back(path);
    if (ReadLibrary(path, &lib.script)) {
      lib.path = path;
      return lib;
    }
    lib.script.clear();
  }
  lib.missing = "plotly.js not found";
  for (size_t i = 0; i < tried.size(); ++i) lib.missing += (i ? ", " : " (tried ") + tried[i];
  if (!tried.empty()) lib.missing += ")";
  lib.missing += ": the report has no 3-D view; run scripts/install_deps.sh (it installs "
                 "plotly.js-gl3d-dist-min from npm) or set RODFIT_PLOTLY_JS to the file";
  return lib;
}

}  // namespace

const PlotlyLibrary& FindPlotlyLibrary() {
  static const PlotlyLibrary library = Find();
  return library;
}

}  // namespace rodfit
