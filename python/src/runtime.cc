// rodfit.Runtime: the runtime (rodfit/runtime/runtime.h) for a Python loop (docs/python.md,
// "Runtime"). A thin wrapper: each method is one Runtime call; numbers cross as float64 numpy
// arrays in SI units, unchanged, so a loop in Python gives the C++ loop's results bit for bit.
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include "bindings.h"
#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"

namespace rodfit_python {

namespace {

using RowsX3 = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using TrianglesX3 = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

// The status as a short name (rodfit::ToString gives the sentence).
const char* StatusName(rodfit::StepStatus status) {
  switch (status) {
    case rodfit::StepStatus::kConverged: return "converged";
    case rodfit::StepStatus::kNotConverged: return "not_converged";
    case rodfit::StepStatus::kTimeBudget: return "time_budget";
    case rodfit::StepStatus::kStrainLimit: return "strain_limit";
    case rodfit::StepStatus::kToolRefused: return "tool_refused";
  }
  return "unknown";
}

// The runtime with the last tick's report. A Runtime is not thread-safe and Step() runs without
// the GIL, so every call takes the instance's lock: two Python threads sharing one runtime are
// serialised instead of racing (uncontended, the lock costs tens of nanoseconds).
class PyRuntime {
 public:
  PyRuntime(const rodfit::Profile& profile, const rodfit::RuntimeOptions& options)
      : runtime_(profile, options) {}

  Eigen::Vector3d Step(const std::optional<Eigen::Vector3d>& tool,
                       const std::optional<Eigen::Matrix3d>& rotation) {
    std::lock_guard<std::mutex> lock(mutex_);
    const bool poke = runtime_.options().tool == rodfit::ToolKind::kPoke;
    if (tool) {
      if (poke) runtime_.SetToolForce(*tool);
      else runtime_.SetToolPosition(*tool);
    }
    if (rotation) {
      if (poke || !runtime_.options().hold_orientation)
        throw std::invalid_argument(
            "tool_rotation: only for a grasp that holds the orientation (hold_orientation=True)");
      runtime_.SetToolOrientation(*rotation);
    }
    {
      py::gil_scoped_release release;
      report_ = runtime_.Step();
    }
    message_ = report_.message;  // the runtime's buffer is valid until the next Step() only
    ++ticks_;
    return runtime_.ToolForce();
  }

  py::dict Status() {
    std::lock_guard<std::mutex> lock(mutex_);
    py::dict out;
    out["status"] = ticks_ ? StatusName(report_.status) : "constructed";
    out["description"] = ticks_ ? rodfit::ToString(report_.status) : "no tick yet";
    out["ok"] = ticks_ == 0 || report_.ok();
    out["advanced"] = ticks_ == 0 || report_.advanced();
    out["message"] = message_;
    out["iterations"] = report_.iterations;
    out["residual"] = report_.residual;
    out["seconds"] = report_.seconds;
    out["tool_lag"] = report_.tool_lag;
    out["tool_turn_lag"] = report_.tool_turn_lag;
    out["ticks"] = ticks_;
    out["time"] = runtime_.time();
    return out;
  }

  RowsX3 Shape() {
    std::lock_guard<std::mutex> lock(mutex_);
    return runtime_.Shape().transpose();
  }
  Eigen::Vector3d ToolPosition() {
    std::lock_guard<std::mutex> lock(mutex_);
    return runtime_.ToolPosition();
  }
  Eigen::Vector3d ToolForce() {
    std::lock_guard<std::mutex> lock(mutex_);
    return runtime_.ToolForce();
  }
  Eigen::Vector3d ToolTorque() {
    std::lock_guard<std::mutex> lock(mutex_);
    return runtime_.ToolTorque();
  }
  Eigen::Matrix3d ToolOrientation() {
    std::lock_guard<std::mutex> lock(mutex_);
    return runtime_.ToolOrientation();
  }
  double Energy() {
    std::lock_guard<std::mutex> lock(mutex_);
    return runtime_.Energy();
  }
  double KineticEnergy() {
    std::lock_guard<std::mutex> lock(mutex_);
    return runtime_.KineticEnergy();
  }
  double Time() {
    std::lock_guard<std::mutex> lock(mutex_);
    return runtime_.time();
  }
  py::dict Mesh() {
    std::lock_guard<std::mutex> lock(mutex_);
    {
      py::gil_scoped_release release;
      runtime_.Mesh(&mesh_);
    }
    TrianglesX3 triangles(mesh_.triangles.size(), 3);
    for (size_t k = 0; k < mesh_.triangles.size(); ++k)
      triangles.row(static_cast<Eigen::Index>(k)) = mesh_.triangles[k].transpose();
    py::dict out;
    out["vertices"] = RowsX3(mesh_.vertices.transpose());
    out["triangles"] = triangles;
    out["rings"] = mesh_.rings;
    out["ring_vertices"] = mesh_.ring_vertices;
    out["radius"] = mesh_.radius;
    return out;
  }

 private:
  std::mutex mutex_;
  rodfit::Runtime runtime_;
  rodfit::StepReport report_;
  std::string message_;
  long ticks_ = 0;
  rodfit::TubeMesh mesh_;  // reused: the runtime's allocation-free Mesh(TubeMesh*)
};

}  // namespace

void BindRuntime(py::module_& m) {
  py::class_<PyRuntime>(
      m, "Runtime",
      "The fitted rod at haptic rate (docs/library.md, \"Runtime\"): built from a Profile, with "
      "the tool (a grasp or a poke) at arc length tool_s [m]. Units: SI (m, N, s).")
      .def(py::init([](const rodfit::Profile& profile, const std::string& mode,
                       const py::kwargs& keywords) {
             // RuntimeOptions by keyword, read through its Serialize (runtime_settings.cc): the
             // defaults, ranges and words are the library's; None keeps a default (tool_s's is
             // the tip).
             py::dict given;
             given["mode"] = mode;
             for (const auto& item : keywords)
               if (!item.second.is_none()) given[item.first] = item.second;
             rodfit::RuntimeOptions options;
             options.tool_s = profile.scene.rod.length;
             DictSettings settings(given);
             rodfit::Serialize(&settings, &options);
             settings.CheckAllRead();
             py::gil_scoped_release release;  // the first equilibrium is a solve
             return new PyRuntime(profile, options);
           }),
           py::arg("profile"), py::arg("mode") = "quasi_static",
           "RuntimeOptions by keyword (rodfit/runtime/runtime.h, their defaults and ranges): "
           "tool_s [m] (default: the tip), tool ('grasp' or 'poke'), time_step [s], time_budget "
           "[s] (0: none), gradient_tolerance, step_tolerance, max_iterations, "
           "dynamic_newton_iterations, max_tool_move, max_strain, mesh_ring_vertices, "
           "hold_orientation. Raises ValueError for invalid options, TypeError for an unknown "
           "keyword, RuntimeError when the first equilibrium is not found.")
      .def("step", &PyRuntime::Step, py::arg("tool") = py::none(),
           py::arg("tool_rotation") = py::none(),
           "One tick: a grasp moves its point towards `tool` [m, shape (3,)] (with "
           "hold_orientation, `tool_rotation` [3x3, world from tool] turns it), a poke applies "
           "the force `tool` [N]; None keeps the last. Returns the force the rod exerts on the "
           "tool [N, shape (3,)]. Never raises for a tick that fails: status() says how it "
           "ended (the last good state is kept).")
      .def("status", &PyRuntime::Status,
           "The last tick's report: status ('converged', 'not_converged', 'time_budget', "
           "'strain_limit', 'tool_refused'; 'constructed' before the first), description, ok, advanced, message, "
           "iterations, residual [N], seconds [s], tool_lag [m], tool_turn_lag [rad], ticks, "
           "time [s].")
      .def("tool_position", &PyRuntime::ToolPosition,
           "Where the tool is: the grasped point, or the poked point of the centre-line [m, (3,)].")
      .def("tool_force", &PyRuntime::ToolForce, "Force the rod exerts on the tool [N, (3,)].")
      .def("tool_torque", &PyRuntime::ToolTorque,
           "Torque the rod exerts on the tool about the grasped point [N m, (3,)] (an oriented "
           "grasp; else zero).")
      .def("tool_orientation", &PyRuntime::ToolOrientation,
           "The rotation the held edge has now [3x3] (the identity without an oriented grasp).")
      .def("shape", &PyRuntime::Shape, "The centre-line, one row per vertex [m, (n+1, 3)].")
      .def("mesh", &PyRuntime::Mesh,
           "The tissue's tube surface: {'vertices': (V, 3) [m], 'triangles': (T, 3) int, "
           "'rings', 'ring_vertices', 'radius' [m]} (a poke's dent included).")
      .def("energy", &PyRuntime::Energy, "Potential energy, the tool's work included [J].")
      .def("kinetic_energy", &PyRuntime::KineticEnergy, "Kinetic energy [J] (dynamic mode).")
      .def_property_readonly("time", &PyRuntime::Time, "Simulated time [s] (dynamic mode).");
}

}  // namespace rodfit_python
