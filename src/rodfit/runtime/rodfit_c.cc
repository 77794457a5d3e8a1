// The C interface (rodfit/runtime/rodfit_c.h) over Runtime: every entry point catches every
// exception and turns it into a status code and a message kept in the handle.
#include "rodfit/runtime/rodfit_c.h"

#include <algorithm>
#include <cstring>
#include <memory>
#include <exception>
#include <limits>
#include <new>
#include <stdexcept>
#include <string>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"

struct rodfit_runtime {
  std::unique_ptr<rodfit::Runtime> runtime;
  std::string last_error;
  // A step's failure is reported with the runtime's message (a fixed text or one formatted in
  // the runtime's own buffer): the step path allocates nothing.
  const char* step_error = nullptr;
  rodfit::TubeMesh mesh;  // rodfit_get_mesh's, its storage reused from call to call
};

namespace {

void CopyMessage(const std::string& message, char* out, size_t capacity) {
  if (!out || capacity == 0) return;
  const size_t n = std::min(message.size(), capacity - 1);
  std::memcpy(out, message.data(), n);
  out[n] = '\0';
}

// Runs `body` on a handle, mapping exceptions to codes and keeping the message.
template <typename F>
rodfit_status Guard(rodfit_runtime* h, F&& body) {
  if (!h) return RODFIT_INVALID_ARGUMENT;
  try {
    h->last_error.clear();  // keeps its capacity: no allocation
    h->step_error = nullptr;
    return body();
  } catch (const std::bad_alloc&) {
    h->last_error = "out of memory";
    return RODFIT_OUT_OF_MEMORY;
  } catch (const std::invalid_argument& e) {
    h->last_error = e.what();
    return RODFIT_INVALID_ARGUMENT;
  } catch (const std::exception& e) {
    h->last_error = e.what();
    return RODFIT_SOLVE_ERROR;
  } catch (...) {
    h->last_error = "unknown error";
    return RODFIT_INTERNAL_ERROR;
  }
}

rodfit_status Fail(rodfit_runtime* h, rodfit_status status, const char* message) {
  h->last_error = message;
  return status;
}

}  // namespace

extern "C" {

void rodfit_default_options(rodfit_options* o) {
  if (!o) return;
  const rodfit::RuntimeOptions d;
  o->mode = RODFIT_MODE_QUASI_STATIC;
  o->tool = RODFIT_TOOL_GRASP;
  o->tool_s = d.tool_s;
  o->max_iterations = d.max_iterations;
  o->gradient_tolerance = d.gradient_tolerance;
  o->time_budget = d.time_budget;
  o->time_step = d.time_step;
  o->mesh_ring_vertices = d.mesh_ring_vertices;
  o->hold_orientation = d.hold_orientation ? 1 : 0;
}

rodfit_status rodfit_create(const char* profile_path, const rodfit_options* options,
                            const char* const* set_names, const double* set_values, int num_sets,
                            rodfit_runtime** out, char* error, size_t error_capacity) {
  if (out) *out = nullptr;
  CopyMessage("", error, error_capacity);
  if (!profile_path || !options || !out || num_sets < 0 ||
      (num_sets > 0 && (!set_names || !set_values))) {
    CopyMessage("rodfit_create: a required pointer is null (or num_sets < 0)", error,
                error_capacity);
    return RODFIT_INVALID_ARGUMENT;
  }
  try {
    rodfit::ProfileReadOptions read;
    for (int k = 0; k < num_sets; ++k) {
      if (!set_names[k]) throw std::invalid_argument("rodfit_create: set_names has a null entry");
      read.overrides[set_names[k]] = set_values[k];
    }
    rodfit::RuntimeOptions o;
    if (options->mode != RODFIT_MODE_QUASI_STATIC && options->mode != RODFIT_MODE_DYNAMIC)
      throw std::invalid_argument("options.mode: unknown mode");
    if (options->tool != RODFIT_TOOL_GRASP && options->tool != RODFIT_TOOL_POKE)
      throw std::invalid_argument("options.tool: unknown tool");
    o.mode = options->mode == RODFIT_MODE_DYNAMIC ? rodfit::RuntimeMode::kDynamic
                                                  : rodfit::RuntimeMode::kQuasiStatic;
    o.tool = options->tool == RODFIT_TOOL_POKE ? rodfit::ToolKind::kPoke : rodfit::ToolKind::kGrasp;
    o.tool_s = options->tool_s;
    o.max_iterations = options->max_iterations;
    o.gradient_tolerance = options->gradient_tolerance;
    o.time_budget = options->time_budget;
    o.time_step = options->time_step;
    o.mesh_ring_vertices = options->mesh_ring_vertices;
    o.hold_orientation = options->hold_orientation != 0;
    const rodfit::Profile profile = rodfit::LoadProfile(profile_path, read);
    auto handle = std::make_unique<rodfit_runtime>();
    handle->runtime = std::make_unique<rodfit::Runtime>(profile, o);
    *out = handle.release();
    return RODFIT_OK;
  } catch (const rodfit::ProfileError& e) {
    CopyMessage(e.what(), error, error_capacity);
    return RODFIT_PROFILE_ERROR;
  } catch (const std::bad_alloc&) {
    CopyMessage("out of memory", error, error_capacity);
    return RODFIT_OUT_OF_MEMORY;
  } catch (const std::invalid_argument& e) {
    CopyMessage(e.what(), error, error_capacity);
    return RODFIT_INVALID_ARGUMENT;
  } catch (const std::exception& e) {
    CopyMessage(e.what(), error, error_capacity);
    return RODFIT_SOLVE_ERROR;
  } catch (...) {
    CopyMessage("unknown error", error, error_capacity);
    return RODFIT_INTERNAL_ERROR;
  }
}

void rodfit_destroy(rodfit_runtime* runtime) { delete runtime; }

rodfit_status rodfit_set_tool_position(rodfit_runtime* h, const double p[3]) {
  return Guard(h, [&] {
    if (!p) return Fail(h, RODFIT_INVALID_ARGUMENT, "position is null");
    h->runtime->SetToolPosition(rodfit::Vec3(p[0], p[1], p[2]));
    return RODFIT_OK;
  });
}

rodfit_status rodfit_set_tool_force(rodfit_runtime* h, const double f[3]) {
  return Guard(h, [&] {
    if (!f) return Fail(h, RODFIT_INVALID_ARGUMENT, "force is null");
    h->runtime->SetToolForce(rodfit::Vec3(f[0], f[1], f[2]));
    return RODFIT_OK;
  });
}

rodfit_status rodfit_set_tool_orientation(rodfit_runtime* h, const double r[9]) {
  return Guard(h, [&] {
    if (!r) return Fail(h, RODFIT_INVALID_ARGUMENT, "rotation is null");
    Eigen::Matrix3d rotation;
    rotation << r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7], r[8];
    h->runtime->SetToolOrientation(rotation);
    return RODFIT_OK;
  });
}

rodfit_status rodfit_step(rodfit_runtime* h, rodfit_step_info* info) {
  return Guard(h, [&] {
    const rodfit::StepReport r = h->runtime->Step();
    rodfit_status status = RODFIT_INTERNAL_ERROR;
    switch (r.status) {
      case rodfit::StepStatus::kConverged: status = RODFIT_OK; break;
      case rodfit::StepStatus::kNotConverged: status = RODFIT_NOT_CONVERGED; break;
      case rodfit::StepStatus::kTimeBudget: status = RODFIT_TIME_BUDGET; break;
      case rodfit::StepStatus::kStrainLimit: status = RODFIT_STRAIN_LIMIT; break;
      case rodfit::StepStatus::kToolRefused: status = RODFIT_TOOL_REFUSED; break;
    }
    if (info) {
      info->status = status;
      info->iterations = r.iterations;
      info->residual = r.residual;
      info->seconds = r.seconds;
      info->tool_lag = r.tool_lag;
    }
    if (status != RODFIT_OK) h->step_error = r.message;
    return status;
  });
}

int rodfit_num_vertices(const rodfit_runtime* h) {
  return h ? h->runtime->model().num_vertices() : 0;
}

rodfit_status rodfit_get_shape(rodfit_runtime* h, double* xyz, size_t capacity) {
  return Guard(h, [&] {
    const rodfit::Mat3X& x = h->runtime->Shape();
    const size_t needed = 3 * static_cast<size_t>(x.cols());
    if (!xyz || capacity < needed)
      return Fail(h, RODFIT_INVALID_ARGUMENT, "shape buffer is null or too small");
    std::memcpy(xyz, x.data(), needed * sizeof(double));  // column-major: xyz per vertex
    return RODFIT_OK;
  });
}

rodfit_status rodfit_get_tool_force(rodfit_runtime* h, double force[3], double torque[3]) {
  return Guard(h, [&] {
    const rodfit::Vec3 f = h->runtime->ToolForce(), t = h->runtime->ToolTorque();
    for (int i = 0; i < 3; ++i) {
      if (force) force[i] = f[i];
      if (torque) torque[i] = t[i];
    }
    return RODFIT_OK;
  });
}

rodfit_status rodfit_get_tool_position(rodfit_runtime* h, double p[3]) {
  return Guard(h, [&] {
    if (!p) return Fail(h, RODFIT_INVALID_ARGUMENT, "position is null");
    const rodfit::Vec3 x = h->runtime->ToolPosition();
    for (int c = 0; c < 3; ++c) p[c] = x[c];
    return RODFIT_OK;
  });
}

rodfit_status rodfit_get_tool_orientation(rodfit_runtime* h, double r[9]) {
  return Guard(h, [&] {
    if (!r) return Fail(h, RODFIT_INVALID_ARGUMENT, "rotation is null");
    const Eigen::Matrix3d rotation = h->runtime->ToolOrientation();
    for (int k = 0; k < 9; ++k) r[k] = rotation(k / 3, k % 3);
    return RODFIT_OK;
  });
}

rodfit_status rodfit_get_energy(rodfit_runtime* h, double* potential, double* kinetic) {
  return Guard(h, [&] {
    if (potential) *potential = h->runtime->Energy();
    if (kinetic) *kinetic = h->runtime->KineticEnergy();
    return RODFIT_OK;
  });
}

rodfit_status rodfit_get_mesh(rodfit_runtime* h, int* num_vertices, int* num_triangles,
                              double* vertices, size_t vertex_capacity, int* triangles,
                              size_t triangle_capacity) {
  return Guard(h, [&] {
    // The counts follow from the shape (a ring per vertex, two triangles per quad), so a call
    // for the counts builds nothing.
    // ring_vertices is at most kMaxMeshRingVertices (RuntimeOptions::Check) and the rings are
    // the rod's vertices, so the products do not overflow a size_t; an int holds them only up
    // to INT_MAX / 3 (the callers size their buffers as 3 * count).
    const size_t rings = static_cast<size_t>(h->runtime->Shape().cols());
    const size_t ring_vertices = static_cast<size_t>(h->runtime->options().mesh_ring_vertices);
    const size_t nv = rings * ring_vertices, nt = 2 * (rings - 1) * ring_vertices;
    constexpr size_t kMaxCount = static_cast<size_t>(std::numeric_limits<int>::max() / 3);
    if (nv > kMaxCount || nt > kMaxCount)
      return Fail(h, RODFIT_INVALID_ARGUMENT,
                  "mesh too large: 3 x its vertex or triangle count does not fit an int (fewer "
                  "segments or mesh_ring_vertices)");
    if (num_vertices) *num_vertices = static_cast<int>(nv);
    if (num_triangles) *num_triangles = static_cast<int>(nt);
    if (!vertices && !triangles) return RODFIT_OK;  // counts only
    if (!vertices || vertex_capacity < 3 * nv || !triangles || triangle_capacity < 3 * nt)
      return Fail(h, RODFIT_INVALID_ARGUMENT, "mesh buffers are null or too small");
    rodfit::TubeMesh& mesh = h->mesh;  // kept: no allocation after the first call
    h->runtime->Mesh(&mesh);
    std::memcpy(vertices, mesh.vertices.data(), 3 * nv * sizeof(double));
    for (size_t k = 0; k < nt; ++k)
      for (int c = 0; c < 3; ++c) triangles[3 * k + c] = mesh.triangles[k][c];
    return RODFIT_OK;
  });
}

rodfit_status rodfit_get_rest_knots(rodfit_runtime* h, int* num_knots, double* s_m,
                                    double* k1_per_m, double* k2_per_m, double* tau_per_m,
                                    size_t capacity) {
  return Guard(h, [&] {
    const rodfit::RodSpec& rod = h->runtime->profile().scene.rod;
    const size_t n = rod.rest_curvature_s.size();
    // The profile reader keeps one value per knot in each list (ParseProfile refuses others),
    // and a file's knots are far fewer than an int counts.
    if (rod.rest_curvature_profile.size() != n ||
        n > static_cast<size_t>(std::numeric_limits<int>::max()))
      return Fail(h, RODFIT_INTERNAL_ERROR,
                  "the rest shape's knots and values differ in count, or exceed an int");
    if (num_knots) *num_knots = static_cast<int>(n);
    if (!s_m && !k1_per_m && !k2_per_m && !tau_per_m) return RODFIT_OK;  // the count only
    if (!s_m || !k1_per_m || !k2_per_m || !tau_per_m || capacity < n)
      return Fail(h, RODFIT_INVALID_ARGUMENT, "rest knot buffers are null or too small");
    for (size_t j = 0; j < n; ++j) {
      s_m[j] = rod.rest_curvature_s[j];
      k1_per_m[j] = rod.rest_curvature_profile[j][0];
      k2_per_m[j] = rod.rest_curvature_profile[j][1];
      tau_per_m[j] = rod.rest_curvature_profile[j][2];
    }
    return RODFIT_OK;
  });
}

rodfit_status rodfit_get_rest_curvature(rodfit_runtime* h, double curvature[3]) {
  return Guard(h, [&] {
    if (!curvature) return Fail(h, RODFIT_INVALID_ARGUMENT, "curvature is null");
    const rodfit::Vec3& k = h->runtime->profile().scene.rod.rest_curvature;
    for (int c = 0; c < 3; ++c) curvature[c] = k[c];
    return RODFIT_OK;
  });
}

rodfit_status rodfit_get_rest_shape(rodfit_runtime* h, double* xyz, size_t capacity) {
  return Guard(h, [&] {
    const size_t needed = 3 * static_cast<size_t>(h->runtime->model().num_vertices());
    if (!xyz || capacity < needed)
      return Fail(h, RODFIT_INVALID_ARGUMENT, "rest shape buffer is null or too small");
    const rodfit::Mat3X x = h->runtime->model().RestState().x;
    std::memcpy(xyz, x.data(), needed * sizeof(double));  // column-major: xyz per vertex
    return RODFIT_OK;
  });
}

const char* rodfit_last_error(const rodfit_runtime* h) {
  if (!h) return "null handle";
  return h->step_error ? h->step_error : h->last_error.c_str();
}

const char* rodfit_status_name(rodfit_status status) {
  switch (status) {
    case RODFIT_OK: return "RODFIT_OK";
    case RODFIT_NOT_CONVERGED: return "RODFIT_NOT_CONVERGED";
    case RODFIT_TIME_BUDGET: return "RODFIT_TIME_BUDGET";
    case RODFIT_INVALID_ARGUMENT: return "RODFIT_INVALID_ARGUMENT";
    case RODFIT_PROFILE_ERROR: return "RODFIT_PROFILE_ERROR";
    case RODFIT_SOLVE_ERROR: return "RODFIT_SOLVE_ERROR";
    case RODFIT_OUT_OF_MEMORY: return "RODFIT_OUT_OF_MEMORY";
    case RODFIT_INTERNAL_ERROR: return "RODFIT_INTERNAL_ERROR";
    case RODFIT_STRAIN_LIMIT: return "RODFIT_STRAIN_LIMIT";
    case RODFIT_TOOL_REFUSED: return "RODFIT_TOOL_REFUSED";
  }
  return "RODFIT_UNKNOWN_STATUS";
}

}  // extern "C"
