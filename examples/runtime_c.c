/* Example: the haptic loop of haptic_loop.cc through the C interface (rodfit/runtime/rodfit_c.h),
 * as a game engine or a Python ctypes binding would drive it.
 *
 * Loads the bundled suture profile (data/profiles/suture.json), grasps its tip, moves the tool
 * along a circle for 1000 ticks of 1 ms, each with a time budget of 0.8 ms, and prints the force
 * on the tool every 100 ticks, one line per tick that is not RODFIT_OK (its status, the
 * runtime's reason and the tool's lag), then the tube mesh's size and one summary line:
 *
 *   ticks: N ok, N over the time budget, N not converged, N at the strain limit, N refused
 *
 * The suture is a thread: it runs in dynamic mode unless asked otherwise (docs/library.md,
 * "Choosing the mode": a slack thread snaps between equilibria, which quasi-static ticks can
 * only follow by losing some). Exits 0 when every tick was RODFIT_OK or over the time budget (a
 * busy machine's, reported, not an error); 1 when a tick failed for another reason, a force was
 * not finite or the runtime could not be made. `--glitch` plays a glitching device: a NaN
 * position at tick 300 and the tool 1 m away for ticks 500 to 509, which the runtime refuses
 * and holds at the strain limit, and the program then exits 1. Run from the repository root:
 *
 *   runtime_c [quasi-static|dynamic] [--glitch] */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rodfit/runtime/rodfit_c.h"

int main(int argc, char** argv) {
  const double pi = 3.14159265358979323846;
  rodfit_options options;
  rodfit_default_options(&options);
  options.mode = RODFIT_MODE_DYNAMIC;
  int glitch = 0;
  for (int a = 1; a < argc; ++a) {
    if (strcmp(argv[a], "quasi-static") == 0) {
      options.mode = RODFIT_MODE_QUASI_STATIC;
    } else if (strcmp(argv[a], "dynamic") == 0) {
      options.mode = RODFIT_MODE_DYNAMIC;
    } else if (strcmp(argv[a], "--glitch") == 0) {
      glitch = 1;
    } else {
      fprintf(stderr, "usage: runtime_c [quasi-static|dynamic] [--glitch]\n");
      return EXIT_FAILURE;
    }
  }
  options.tool_s = 0.2;        /* the suture's tip [m] */
  options.time_budget = 8e-4;  /* [s] of the 1 ms tick */
  char error[512];
  rodfit_runtime* rt = NULL;
  rodfit_status status = rodfit_create("data/profiles/suture.json", &options, NULL, NULL, 0, &rt,
                                       error, sizeof(error));
  if (status != RODFIT_OK) {
    fprintf(stderr, "runtime_c: %s: %s\n", rodfit_status_name(status), error);
    return EXIT_FAILURE;
  }
  double home[3];
  rodfit_get_tool_position(rt, home);
  int ok = 0, over_budget = 0, not_converged = 0, strain = 0, refused = 0, other = 0;
  int finite = 1;
  double worst_ms = 0.0;
  for (int k = 1; k <= 1000; ++k) {
    const double phase = 2.0 * pi * k / 1000.0;
    /* A horizontal circle of 1 cm towards the clamp: the thread stays slack. */
    double tool[3] = {home[0] + 0.01 * (cos(phase) - 1.0), home[1] + 0.01 * sin(phase), home[2]};
    if (glitch && k == 300) tool[1] = NAN;
    if (glitch && k >= 500 && k < 510) tool[0] += 1.0;
    rodfit_set_tool_position(rt, tool);
    rodfit_step_info info;
    status = rodfit_step(rt, &info);
    switch (status) {
      case RODFIT_OK: ++ok; break;
      case RODFIT_TIME_BUDGET: ++over_budget; break;
      case RODFIT_NOT_CONVERGED: ++not_converged; break;
      case RODFIT_STRAIN_LIMIT: ++strain; break;
      case RODFIT_TOOL_REFUSED: ++refused; break;
      default: ++other; break;
    }
    if (status != RODFIT_OK)  /* the reason names the tool's lag (info.tool_lag) */
      fprintf(stderr, "tick %d: %s: %s\n", k, rodfit_status_name(status), rodfit_last_error(rt));
    if (1e3 * info.seconds > worst_ms) worst_ms = 1e3 * info.seconds;
    double force[3];
    rodfit_get_tool_force(rt, force, NULL);
    finite = finite && isfinite(force[0]) && isfinite(force[1]) && isfinite(force[2]);
    if (k % 100 == 0)
      printf("tick %4d  force [% .4e % .4e % .4e] N  %.3f ms\n", k, force[0], force[1], force[2],
             1e3 * info.seconds);
  }
  int nv = 0, nt = 0;
  if (rodfit_get_mesh(rt, &nv, &nt, NULL, 0, NULL, 0) != RODFIT_OK) {
    fprintf(stderr, "runtime_c: mesh: %s\n", rodfit_last_error(rt));
    finite = 0;
  }
  printf("%s mode; mesh: %d vertices, %d triangles; slowest tick %.3f ms\n",
         options.mode == RODFIT_MODE_DYNAMIC ? "dynamic" : "quasi-static", nv, nt, worst_ms);
  printf("ticks: %d ok, %d over the time budget, %d not converged, %d at the strain limit, %d "
         "refused\n",
         ok, over_budget, not_converged, strain, refused);
  rodfit_destroy(rt);
  if (!finite) fprintf(stderr, "runtime_c: a force was not finite\n");
  return finite && not_converged + strain + refused + other == 0 ? EXIT_SUCCESS : EXIT_FAILURE;
}
