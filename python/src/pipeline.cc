// rodfit.synth (and, in run.cc, fit / simulate / rollout): the library's entry points for the
// Python package (docs/python.md). Each releases the GIL while it runs.
#include <cstdint>
#include <string>

#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include "bindings.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/synthesize.h"
#include "rodfit/synth/synth.h"

namespace rodfit_python {

namespace {

using RowsX3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;

py::dict Synth(const rodfit::Experiment& experiment, std::uint32_t seed, bool noise_free,
               const std::string& output) {
  rodfit::SynthOptions options;  // as `rodfit synth` sets them (src/cli/synth_command.cc)
  options.seed = seed;
  options.add_noise = !noise_free;
  options.statics = experiment.statics;
  rodfit::SynthBundle bundle;
  {
    py::gil_scoped_release release;
    bundle = output.empty() ? rodfit::MakeSynthBundle(experiment, options)
                            : rodfit::Synthesize(experiment, output, options);
  }
  py::dict files, truth;
  for (const auto& [name, text] : bundle.files) files[py::str(name)] = py::bytes(text);
  for (const rodfit::CaseShape& shape : bundle.truth)
    truth[py::str(shape.name)] = RowsX3(shape.x.transpose());
  py::dict out;
  out["files"] = files;
  out["truth"] = truth;
  out["report"] = bundle.report;
  return out;
}

}  // namespace

void BindRun(py::module_& m);

void BindPipeline(py::module_& m) {
  m.def("synth", &Synth, py::arg("experiment"), py::arg("seed") = 1,
        py::arg("noise_free") = false, py::arg("output") = "",
        "Every observation file of the experiment synthesized from its parameter values (the "
        "truth), as `rodfit synth` makes them: {'files': {name: bytes}, 'truth': {case: (n+1, 3) "
        "[m]}, 'report': [lines]}; written into `output` too when it names a folder (nothing "
        "written on an error). Raises InputError.");
  BindRun(m);
}

}  // namespace rodfit_python
