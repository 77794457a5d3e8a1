/* The runtime's C interface (docs/library.md, "C API"): rodfit/runtime/runtime.h behind an
 * opaque handle, for game engines and other languages (Unity, Unreal, Python ctypes). Every
 * function returns a status code; no C++ exception crosses it. A failed call on a handle leaves
 * its message in rodfit_last_error(handle); a failed rodfit_create writes its message into the
 * caller's buffer. Units are SI, vectors are 3 doubles (x, y, z), shapes are packed xyz per
 * vertex.
 *
 * Thread-safety: one handle per thread (or guard it); distinct handles are independent.
 * rodfit_step allocates no memory, nor does rodfit_get_mesh after its first call with buffers
 * (the handle keeps the mesh's storage). */
#ifndef RODFIT_RUNTIME_RODFIT_C_H_
#define RODFIT_RUNTIME_RODFIT_C_H_

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct rodfit_runtime rodfit_runtime;

/* A step that is not RODFIT_OK leaves its reason in rodfit_last_error (one line, without
 * allocating) and the tool's lag in rodfit_step_info.tool_lag. */
typedef enum rodfit_status {
  RODFIT_OK = 0,
  RODFIT_NOT_CONVERGED = 1,        /* step: last good state kept (rodfit_last_error says why) */
  RODFIT_TIME_BUDGET = 2,          /* step: budget ran out, last good state kept */
  RODFIT_INVALID_ARGUMENT = 3,     /* a null pointer, a bad option, a small buffer */
  RODFIT_PROFILE_ERROR = 4,        /* the profile could not be read or is invalid */
  RODFIT_SOLVE_ERROR = 5,          /* the first equilibrium was not found, or a mesh failed */
  RODFIT_OUT_OF_MEMORY = 6,
  RODFIT_INTERNAL_ERROR = 7,
  RODFIT_STRAIN_LIMIT = 8,         /* step: converged, the grasp held at the strain limit (the
                                    * tool is out of the rod's reach; tool_lag says how far) */
  RODFIT_TOOL_REFUSED = 9          /* step: the tool's position, orientation or force is not
                                    * finite or out of range (the message names the value);
                                    * last good state kept */
} rodfit_status;

enum { RODFIT_MODE_QUASI_STATIC = 0, RODFIT_MODE_DYNAMIC = 1 };
enum { RODFIT_TOOL_GRASP = 0, RODFIT_TOOL_POKE = 1 };

/* RuntimeOptions' fields (rodfit/runtime/runtime.h); fill with rodfit_default_options. */
typedef struct rodfit_options {
  int mode;                   /* RODFIT_MODE_* */
  int tool;                   /* RODFIT_TOOL_* */
  double tool_s;              /* [m] the tool's arc length, in (0, L]; required */
  int max_iterations;         /* Newton iterations per quasi-static step */
  double gradient_tolerance;  /* relative to the rod's load scale */
  double time_budget;         /* [s] per step, 0: none */
  double time_step;           /* [s] dynamic mode */
  int mesh_ring_vertices;     /* rodfit_get_mesh: vertices per ring, in [3, 1024] */
  int hold_orientation;       /* quasi-static grasp: 1 holds the tool's orientation (a clamp) */
} rodfit_options;

typedef struct rodfit_step_info {
  int status;        /* rodfit_status of the step */
  int iterations;    /* Newton iterations */
  double residual;   /* [N] scaled residual at exit */
  double seconds;    /* wall time of the step */
  double tool_lag;   /* [m] grasp: how far the grasped point is from the tool after the step */
} rodfit_step_info;

void rodfit_default_options(rodfit_options* options);

/* Loads the profile and builds the rod. `set_names`/`set_values` (num_sets entries, may be
 * NULL when 0) give values for parameters the profile leaves undetermined, or replace its own.
 * On failure *out is NULL and `error` (capacity bytes, may be NULL) holds one line. */
rodfit_status rodfit_create(const char* profile_path, const rodfit_options* options,
                            const char* const* set_names, const double* set_values, int num_sets,
                            rodfit_runtime** out, char* error, size_t error_capacity);
void rodfit_destroy(rodfit_runtime* runtime);

rodfit_status rodfit_set_tool_position(rodfit_runtime* runtime, const double position[3]);
rodfit_status rodfit_set_tool_force(rodfit_runtime* runtime, const double force[3]);
/* Oriented grasp (options.hold_orientation): the tool's rotation, world from tool, 9 doubles
 * row-major; the identity is the orientation at creation. */
rodfit_status rodfit_set_tool_orientation(rodfit_runtime* runtime, const double rotation[9]);
/* One tick; `info` may be NULL. */
rodfit_status rodfit_step(rodfit_runtime* runtime, rodfit_step_info* info);

int rodfit_num_vertices(const rodfit_runtime* runtime);
/* Writes 3 * rodfit_num_vertices doubles; capacity in doubles. */
rodfit_status rodfit_get_shape(rodfit_runtime* runtime, double* xyz, size_t capacity);
/* Force [N] and torque [N m] the rod exerts on the tool; either may be NULL. */
rodfit_status rodfit_get_tool_force(rodfit_runtime* runtime, double force[3], double torque[3]);
/* Where the tool is on the rod [m]: the grasped point, or the poked point of the centre-line. */
rodfit_status rodfit_get_tool_position(rodfit_runtime* runtime, double position[3]);
/* The rotation the grasp holds now (world from tool, 9 doubles row-major; the identity without
 * an oriented grasp): it turns towards the tool's at most max_tool_move radians per tick. */
rodfit_status rodfit_get_tool_orientation(rodfit_runtime* runtime, double rotation[9]);
/* The rod's potential energy [J] (a poke's -f . x included) and kinetic energy [J] (0 in
 * quasi-static mode); either may be NULL. */
rodfit_status rodfit_get_energy(rodfit_runtime* runtime, double* potential, double* kinetic);
/* The tube mesh (with a poke's dent): counts first (vertices, triangles), then, when the
 * buffers are large enough (3 doubles per vertex, 3 ints per triangle), the data. Pass NULL
 * buffers to ask for the counts only (they follow from the segments and
 * mesh_ring_vertices: nothing is built). A mesh whose 3 ints per triangle would not fit an int
 * is refused (RODFIT_INVALID_ARGUMENT), never counted negative. */
rodfit_status rodfit_get_mesh(rodfit_runtime* runtime, int* num_vertices, int* num_triangles,
                              double* vertices, size_t vertex_capacity, int* triangles,
                              size_t triangle_capacity);

/* The rod's rest shape, as the profile gives it and the runtime builds the rod from
 * (`rod.rest_shape` and `rod.rest_curvature`, docs/formats.md "Profile JSON"). The knots: the
 * intrinsic curvature k1, k2 and tau [1/m] at arc lengths s [m] (increasing), linear between
 * knots and constant beyond them, added to the uniform rest curvature. Counts first: *num_knots
 * (0: no rest shape; num_knots may be NULL); with the four arrays NULL nothing else is written,
 * otherwise each must hold `capacity` doubles, at least the knots. */
rodfit_status rodfit_get_rest_knots(rodfit_runtime* runtime, int* num_knots, double* s_m,
                                    double* k1_per_m, double* k2_per_m, double* tau_per_m,
                                    size_t capacity);
/* The uniform rest curvature (k1, k2, tau) [1/m] the knots add to (0 0 0 unless the profile
 * gives `rod.rest_curvature`). */
rodfit_status rodfit_get_rest_curvature(rodfit_runtime* runtime, double curvature[3]);
/* The rod's centre-line at rest [m], on the runtime's vertices: the unloaded rest shape from the
 * clamp along its tangent (no gravity, no other held point). Writes 3 * rodfit_num_vertices
 * doubles; capacity in doubles. Computed on each call: it allocates (not for the loop). */
rodfit_status rodfit_get_rest_shape(rodfit_runtime* runtime, double* xyz, size_t capacity);

/* The message of the handle's last failed call ("" when none); valid until the next call. */
const char* rodfit_last_error(const rodfit_runtime* runtime);
/* A status code's name, e.g. "RODFIT_NOT_CONVERGED". */
const char* rodfit_status_name(rodfit_status status);

#ifdef __cplusplus
}
#endif

#endif /* RODFIT_RUNTIME_RODFIT_C_H_ */
