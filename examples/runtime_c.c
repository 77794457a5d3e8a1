/* Example: the haptic loop of haptic_loop.cc through the C interface (rodfit/runtime/rodfit_c.h),
 * as a game engine or a Python ctypes binding would drive it.
 *
 * Loads the bundled suture profile (data/profiles/suture.json), grasps its tip, moves the tool
 * along a circle for 1000 ticks of 1 ms and prints the force on the tool every 100 ticks, then
 * the tube mesh's size. Exits 0 when every tick converged. Run from the repository root. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "rodfit/runtime/rodfit_c.h"

int main(void) {
  const double pi = 3.14159265358979323846;
  rodfit_options options;
  rodfit_default_options(&options);
  options.tool_s = 0.2; /* the suture's tip [m] */
  char error[512];
  rodfit_runtime* rt = NULL;
  rodfit_status status = rodfit_create("data/profiles/suture.json", &options, NULL, NULL, 0, &rt,
                                       error, sizeof(error));
  if (status != RODFIT_OK) {
    fprintf(stderr, "runtime_c: %s: %s\n", rodfit_status_name(status), error);
    return EXIT_FAILURE;
  }
  const int n = rodfit_num_vertices(rt);
  double* shape = malloc(3 * (size_t)n * sizeof(double));
  if (!shape) return EXIT_FAILURE;
  rodfit_get_shape(rt, shape, 3 * (size_t)n);
  const double home[3] = {shape[3 * (n - 1)], shape[3 * (n - 1) + 1], shape[3 * (n - 1) + 2]};
  int missed = 0, finite = 1;
  double worst_ms = 0.0;
  for (int k = 1; k <= 1000; ++k) {
    const double phase = 2.0 * pi * k / 1000.0;
    /* A horizontal circle of 1 cm towards the clamp: the thread stays slack. */
    const double tool[3] = {home[0] + 0.01 * (cos(phase) - 1.0), home[1] + 0.01 * sin(phase),
                            home[2]};
    rodfit_set_tool_position(rt, tool);
    rodfit_step_info info;
    status = rodfit_step(rt, &info);
    if (status != RODFIT_OK) {
      ++missed;
      fprintf(stderr, "tick %d: %s (%s)\n", k, rodfit_status_name(status), rodfit_last_error(rt));
    }
    if (1e3 * info.seconds > worst_ms) worst_ms = 1e3 * info.seconds;
    if (k % 100 == 0) {
      double force[3];
      rodfit_get_tool_force(rt, force, NULL);
      finite = finite && isfinite(force[0]) && isfinite(force[1]) && isfinite(force[2]);
      printf("tick %4d  force [% .4e % .4e % .4e] N  %.3f ms\n", k, force[0], force[1], force[2],
             1e3 * info.seconds);
    }
  }
  int nv = 0, nt = 0;
  if (rodfit_get_mesh(rt, &nv, &nt, NULL, 0, NULL, 0) != RODFIT_OK) {
    fprintf(stderr, "runtime_c: mesh: %s\n", rodfit_last_error(rt));
    finite = 0;
  }
  printf("mesh: %d vertices, %d triangles; slowest tick %.3f ms; %d ticks missed\n", nv, nt,
         worst_ms, missed);
  free(shape);
  rodfit_destroy(rt);
  return finite ? EXIT_SUCCESS : EXIT_FAILURE;
}
