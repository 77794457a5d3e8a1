// A tick does not allocate: this test program interposes malloc and its family (glibc resolves
// them to the executable's definitions first; operator new and Eigen's dynamic matrices both
// allocate through malloc; under AddressSanitizer, ASan's allocation hook instead, see below) and
// counts calls while a flag is up, around ticks of every kind — a
// drag (quasi-static, with and without the held orientation, and dynamic) and a poke
// (quasi-static and dynamic) — each read back as a haptic loop does: Step(), the shape, the tool's force and torque, and the tube
// mesh with the poke's dent into a kept buffer (Runtime::Mesh(TubeMesh*)). Every other test of
// the program runs with the flag down; the program's other files count through
// allocation_counter.h (the tool-path torture test does).
#include <atomic>
#include <cstdlib>
#include <cmath>
#include <cstddef>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/runtime.h"
#include "runtime/allocation_counter.h"

// AddressSanitizer owns malloc: its run-time library defines malloc and its family, and the
// executable's definitions below would win over them, so that (1) the program's heap would be
// glibc's, unchecked, and (2) the first allocation — made by the dynamic loader inside ASan's own
// start-up, before ASan has mapped its shadow memory — runs Count() (instrumented code reading
// g_counting through the shadow) and the program dies of SIGSEGV before main. Under ASan the
// count therefore comes from ASan's allocation hook instead (the sanitizers' public
// __sanitizer_install_malloc_and_free_hooks, declared in LLVM's sanitizer/allocator_interface.h,
// which GCC does not install; libasan exports it), called for every allocation the program makes:
// malloc, calloc, realloc, the aligned allocators and operator new. Same count, same test.
#if defined(__SANITIZE_ADDRESS__)
#define RODFIT_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RODFIT_TEST_ASAN 1
#endif
#endif

#ifdef RODFIT_TEST_ASAN
extern "C" int __sanitizer_install_malloc_and_free_hooks(
    void (*malloc_hook)(const volatile void* p, std::size_t size),
    void (*free_hook)(const volatile void* p));
#else
extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);
}
#endif

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_allocations{0};
void Count() {
  if (g_counting.load(std::memory_order_relaxed)) {
    g_allocations.fetch_add(1);
    if (std::getenv("RODFIT_TRAP_ALLOCATION")) __builtin_trap();  // debugging: where from
  }
}

#ifdef RODFIT_TEST_ASAN
void CountHook(const volatile void*, std::size_t) { Count(); }
void IgnoreFree(const volatile void*) {}
// Installed once, before main (ASan is initialised before any of the program's constructors);
// 0 when ASan has no free hook slot left, which StartCounting() reports as a failure rather than
// counting nothing.
const int g_hook_installed = __sanitizer_install_malloc_and_free_hooks(&CountHook, &IgnoreFree);
#endif

// Starts counting from zero.
void StartCounting() {
#ifdef RODFIT_TEST_ASAN
  if (g_hook_installed == 0) ADD_FAILURE() << "ASan refused the allocation hook: nothing counted";
#endif
  g_allocations = 0;
  g_counting = true;
}
}  // namespace

#ifndef RODFIT_TEST_ASAN
extern "C" {
void* malloc(std::size_t size) {
  Count();
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) {
  Count();
  return __libc_calloc(count, size);
}
void* realloc(void* p, std::size_t size) {
  Count();
  return __libc_realloc(p, size);
}
void* memalign(std::size_t alignment, std::size_t size) {
  Count();
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) {
  Count();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) {
  Count();
  *out = __libc_memalign(alignment, size);
  return *out ? 0 : 12;  // ENOMEM
}
void free(void* p) { __libc_free(p); }
}
#endif

namespace rodfit_test {

void StartCountingAllocations() { StartCounting(); }

long StopCountingAllocations() {
  g_counting = false;
  return g_allocations.load();
}

}  // namespace rodfit_test

namespace rodfit {
namespace {

long AllocationsDuring(const std::function<void(int)>& tick, int ticks) {
  StartCounting();
  for (int k = 0; k < ticks; ++k) tick(k);
  g_counting = false;
  return g_allocations.load();
}

struct Mode {
  const char* profile;
  RuntimeMode mode;
  ToolKind tool;
  double s;
  bool hold_orientation = false;
};

void PrintTo(const Mode& m, std::ostream* os) { *os << m.profile << " s = " << m.s; }
std::string ModeName(const ::testing::TestParamInfo<Mode>& info) {
  std::string name = info.param.profile;
  name = name.substr(0, name.find('.'));
  name += info.param.mode == RuntimeMode::kDynamic ? "_dynamic" : "_quasi_static";
  name += info.param.hold_orientation ? "_oriented" : "";
  return name + (info.param.tool == ToolKind::kPoke ? "_poke" : "_grasp");
}

class NoAllocation : public ::testing::TestWithParam<Mode> {};

TEST_P(NoAllocation, InStep) {
  const Mode m = GetParam();
  const Profile p = LoadProfile(std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + m.profile);
  RuntimeOptions options;
  options.mode = m.mode;
  options.tool = m.tool;
  options.tool_s = m.s;
  options.hold_orientation = m.hold_orientation;
  Runtime rt(p, options);
  const Vec3 home = rt.ToolPosition();
  // The loop's buffers, sized once before it as a simulator sizes its vertex buffer.
  TubeMesh mesh;
  rt.Mesh(&mesh);
  const TubeMesh first = mesh;
  int failed = 0;
  double sum = 0.0;  // of what is read back, so that none of it is optimised away
  const long count = AllocationsDuring(
      [&](int k) {
        const double phase = 0.01 * k;
        if (m.tool == ToolKind::kGrasp)
          rt.SetToolPosition(home + 0.005 * Vec3(0.0, std::sin(phase), 1.0 - std::cos(phase)));
        else
          rt.SetToolForce(Vec3(0.0, 0.0, -0.05 * (1.0 - std::cos(phase))));
        if (m.hold_orientation)
          rt.SetToolOrientation(Eigen::AngleAxisd(0.2 * std::sin(phase), Vec3::UnitX()).matrix());
        if (!rt.Step().ok()) ++failed;
        rt.Mesh(&mesh);
        sum += rt.Shape().sum() + rt.ToolForce().sum() + rt.ToolTorque().sum() +
               mesh.vertices.sum();
      },
      300);
  EXPECT_EQ(failed, 0);
  EXPECT_TRUE(std::isfinite(sum));
  EXPECT_EQ(count, 0) << "malloc called " << count << " times in 300 ticks";
  // The mesh moved with the rod (and, for the poke, was dented): the read-back is live.
  EXPECT_GT((mesh.vertices - first.vertices).cwiseAbs().maxCoeff(), 1e-4);
  // The counter works: an allocation with the flag up is seen.
  g_counting = true;
  auto* probe = new std::vector<double>(10);
  g_counting = false;
  delete probe;
  EXPECT_GE(g_allocations.load(), 1);
}

// Nor does a tick that fails: out of its time budget, or out of Newton iterations after a far
// jump of the tool (a device glitch), in either mode — the haptic loop's worst ticks are the
// ones that must not stall on the heap.
TEST_P(NoAllocation, InFailedSteps) {
  const Mode m = GetParam();
  const Profile p = LoadProfile(std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + m.profile);
  for (const bool budget : {true, false}) {
    RuntimeOptions options;
    options.mode = m.mode;
    options.tool = m.tool;
    options.tool_s = m.s;
    options.hold_orientation = m.hold_orientation;
    options.max_iterations = 1;
    options.dynamic_newton_iterations = 1;
    if (budget) options.time_budget = 1e-12;  // below any Newton iteration's cost
    Runtime rt(p, options);
    const Vec3 home = rt.ToolPosition();
    const double L = p.scene.rod.length;
    int failed = 0;
    const long count = AllocationsDuring(
        [&](int k) {
          const double sign = (k % 2) ? 1.0 : -1.0;
          if (m.tool == ToolKind::kGrasp)
            rt.SetToolPosition(home + 0.3 * L * Vec3(0.0, sign, 0.5));
          else
            rt.SetToolForce(Vec3(0.0, 0.0, sign * 50.0 * p.scene.material.ring_bend_stiffness /
                                               (L * L) + sign * 0.5));
          if (!rt.Step().ok()) ++failed;
        },
        20);
    EXPECT_GT(failed, 0) << (budget ? "budget" : "iterations");
    EXPECT_EQ(count, 0) << "malloc called " << count << " times in 20 failing ticks ("
                        << (budget ? "budget" : "iterations") << ")";
  }
}

// Nor does a tick that refuses its input or holds the grasp at the strain limit: their messages
// name values (NaN, 1e308, a mirrored rotation, an absurd push) formatted into the runtime's own
// buffer.
TEST_P(NoAllocation, InRefusedAndStrainLimitedSteps) {
  const Mode m = GetParam();
  const Profile p = LoadProfile(std::string(RODFIT_SOURCE_DIR) + "/data/profiles/" + m.profile);
  RuntimeOptions options;
  options.mode = m.mode;
  options.tool = m.tool;
  options.tool_s = m.s;
  options.hold_orientation = m.hold_orientation;
  Runtime rt(p, options);
  const Vec3 home = rt.ToolPosition();
  const double nan = std::nan("");
  int refused = 0, limited = 0;
  const char* last = "";
  const long count = AllocationsDuring(
      [&](int k) {
        if (m.tool == ToolKind::kGrasp) {
          const Vec3 inputs[] = {Vec3(nan, 0.0, 0.0), Vec3(0.0, 1e308, 0.0),
                                 home + Vec3(1.0, 0.0, 0.0), home};
          rt.SetToolPosition(inputs[k % 4]);
        } else {
          const Vec3 inputs[] = {Vec3(0.0, nan, 0.0), Vec3(0.0, 0.0, -1e308), Vec3(0.0, -0.01, 0.0)};
          rt.SetToolForce(inputs[k % 3]);
        }
        if (m.hold_orientation && k % 8 == 7)
          rt.SetToolOrientation(Vec3(1.0, 1.0, -1.0).asDiagonal());
        else if (m.hold_orientation)
          rt.SetToolOrientation(Eigen::Matrix3d::Identity());
        const StepReport r = rt.Step();
        refused += r.status == StepStatus::kToolRefused;
        limited += r.status == StepStatus::kStrainLimit;
        last = r.message;
      },
      40);
  EXPECT_GT(refused, 0);
  if (m.tool == ToolKind::kGrasp) {
    EXPECT_GT(limited, 0);
  }
  EXPECT_NE(last, nullptr);
  EXPECT_EQ(count, 0) << "malloc called " << count << " times in 40 refused or limited ticks";
}

INSTANTIATE_TEST_SUITE_P(
    Ticks, NoAllocation,
    ::testing::Values(Mode{"suture.json", RuntimeMode::kQuasiStatic, ToolKind::kGrasp, 0.2},
                      Mode{"bowel_drag.json", RuntimeMode::kQuasiStatic, ToolKind::kGrasp, 0.1},
                      Mode{"bowel_drag.json", RuntimeMode::kQuasiStatic, ToolKind::kGrasp, 0.1,
                           true},
                      Mode{"bowel_drag.json", RuntimeMode::kDynamic, ToolKind::kGrasp, 0.1},
                      Mode{"bowel_poke.json", RuntimeMode::kQuasiStatic, ToolKind::kPoke, 0.075},
                      Mode{"bowel_poke.json", RuntimeMode::kDynamic, ToolKind::kPoke, 0.075}),
    ModeName);

}  // namespace
}  // namespace rodfit
