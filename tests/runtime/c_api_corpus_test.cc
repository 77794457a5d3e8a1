// Issue 34, item 7: the C API (rodfit/runtime/rodfit_c.h) on a generated corpus of call sequences
// with hostile arguments, from one seed: options with NaN, infinities, 1e308, zero and negative
// counts; tool positions, forces and rotations with the same; null handles and buffers, buffers
// one short; calls in any order (a step before any tool input, getters between steps). Each call
// is judged as a caller would: a status that is one of the codes; a failure with a message
// (rodfit_last_error, or create's error buffer: one line); a success whose outputs are finite
// (the shape, the force and torque, the energies, the rest shape and its knots) — a non-finite
// number returned with RODFIT_OK is "silent", the worst outcome. A crash ends the test program.
// The tallies are printed.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "rodfit/runtime/rodfit_c.h"

namespace {

const std::string kSuture = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/suture.json";

// Hostile and ordinary values of a double argument.
const double kValues[] = {0.0,  -0.0, 1e-3,   0.05, 0.1,   0.2,     -0.1,   1.0,
                          1e308, -1e308, 1e-300, NAN, INFINITY, -INFINITY, 5e-4, 0.19};

struct Tally {
  int calls = 0, ok = 0, clean_error = 0, silent = 0, bad_status = 0;
  std::map<std::string, int> silent_by_call;
};

bool KnownStatus(int s) { return s >= RODFIT_OK && s <= RODFIT_TOOL_REFUSED; }

bool OneLine(const char* text) {
  return text != nullptr && *text != '\0' && std::strchr(text, '\n') == nullptr;
}

// A status of a call on a handle: a failure must carry a message (rodfit_last_error).
// `message`: the handle's rodfit_last_error read right after the call (the next call clears it);
// null for a call on a null handle.
void Judge(Tally* t, const std::string& call, rodfit_status s, const char* message,
           bool outputs_finite) {
  ++t->calls;
  if (!KnownStatus(s)) {
    ++t->bad_status;
    ADD_FAILURE() << call << ": status " << s;
    return;
  }
  // A step that converged at the strain limit, or was refused/ran out of time keeping its last
  // good state, still returns a state: its outputs are judged like a success's.
  const bool state_returned = s == RODFIT_OK || s == RODFIT_STRAIN_LIMIT;
  if (state_returned) {
    if (!outputs_finite) {
      ++t->silent;
      ++t->silent_by_call[call];
      ADD_FAILURE() << call << ": " << rodfit_status_name(s) << " with non-finite outputs";
    } else {
      ++t->ok;
    }
    return;
  }
  // A null handle has nowhere to keep a message; the status says it.
  if (message != nullptr && !OneLine(message)) {
    ++t->silent;
    ++t->silent_by_call[call];
    ADD_FAILURE() << call << ": " << rodfit_status_name(s) << " without a message";
    return;
  }
  ++t->clean_error;
}

bool Finite(const double* v, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(v[i])) return false;
  return true;
}

TEST(CApiCorpus, HostileCallSequencesReturnCodesMessagesAndFiniteResults) {
  std::mt19937 rng(34);
  auto pick = [&]() { return kValues[rng() % (sizeof(kValues) / sizeof(kValues[0]))]; };
  Tally tally;
  int sequences = 0, created = 0;
  constexpr int kSequences = 160, kCallsPerSequence = 24;
  for (int q = 0; q < kSequences; ++q) {
    ++sequences;
    rodfit_options o;
    rodfit_default_options(&o);
    // Half the sequences keep sane options (so that calls on a live handle are reached), the
    // others get one or more hostile fields.
    o.tool_s = 0.1 + 0.09 * ((rng() % 3) - 1.0);
    o.mode = rng() % 2 ? RODFIT_MODE_QUASI_STATIC : RODFIT_MODE_DYNAMIC;
    o.tool = rng() % 4 == 0 ? RODFIT_TOOL_POKE : RODFIT_TOOL_GRASP;
    o.hold_orientation = static_cast<int>(rng() % 2);
    if (rng() % 2) {
      switch (rng() % 9) {
        case 0: o.tool_s = pick(); break;
        case 1: o.max_iterations = static_cast<int>(rng() % 3) - 1; break;
        case 2: o.gradient_tolerance = pick(); break;
        case 3: o.time_budget = pick(); break;
        case 4: o.time_step = pick(); break;
        case 5: o.mesh_ring_vertices = static_cast<int>(rng() % 2 ? 2 : 100000); break;
        case 6: o.mode = 7; break;
        case 7: o.tool = -1; break;
        case 8: o.hold_orientation = 2; break;
      }
    }
    rodfit_runtime* rt = nullptr;
    char error[256] = "untouched";
    const rodfit_status cs =
        rodfit_create(kSuture.c_str(), &o, nullptr, nullptr, 0, &rt, error, sizeof(error));
    ++tally.calls;
    if (!KnownStatus(cs)) {
      ++tally.bad_status;
      ADD_FAILURE() << "create: status " << cs;
      continue;
    }
    if (cs != RODFIT_OK) {
      EXPECT_EQ(rt, nullptr);
      if (rt != nullptr || !OneLine(error)) {
        ++tally.silent;
        ++tally.silent_by_call["create"];
      } else {
        ++tally.clean_error;
      }
      continue;
    }
    ++tally.ok;
    ++created;
    const int n = rodfit_num_vertices(rt);
    ASSERT_GT(n, 1);
    std::vector<double> shape(3 * static_cast<size_t>(n));
    for (int k = 0; k < kCallsPerSequence; ++k) {
      const double v3[3] = {pick(), pick(), pick()};
      switch (rng() % 12) {
        case 0: case 1: {
          // Mostly moves near the rod, sometimes hostile.
          double p[3] = {0.1 + 0.01 * (rng() % 5), 0.005 * (rng() % 3), -0.005 * (rng() % 3)};
          if (rng() % 3 == 0) std::memcpy(p, v3, sizeof(p));
          const rodfit_status st = rodfit_set_tool_position(rt, p);
          Judge(&tally, "set_tool_position", st, rodfit_last_error(rt), true);
          break;
        }
        case 2:
        {
          const rodfit_status st = rodfit_set_tool_force(rt, v3);
          Judge(&tally, "set_tool_force", st, rodfit_last_error(rt), true);
          break;
        }
        case 3: {
          double r[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
          if (rng() % 2) r[rng() % 9] = pick();
          const rodfit_status st = rodfit_set_tool_orientation(rt, r);
          Judge(&tally, "set_tool_orientation", st, rodfit_last_error(rt), true);
          break;
        }
        case 4: case 5: {
          rodfit_step_info info;
          const rodfit_status s = rodfit_step(rt, rng() % 4 ? &info : nullptr);
          const std::string message = rodfit_last_error(rt);
          // The state a step leaves is read back and must be finite whatever it returned.
          const rodfit_status g = rodfit_get_shape(rt, shape.data(), shape.size());
          Judge(&tally, "step", s, message.c_str(),
                g == RODFIT_OK && Finite(shape.data(), shape.size()));
          break;
        }
        case 6: {
          const size_t capacity = rng() % 3 == 0 ? shape.size() - 1 : shape.size();
          double* buffer = rng() % 5 == 0 ? nullptr : shape.data();
          const rodfit_status s = rodfit_get_shape(rt, buffer, capacity);
          Judge(&tally, "get_shape", s, rodfit_last_error(rt), buffer && Finite(buffer, capacity));
          break;
        }
        case 7: {
          double f[3], t[3];
          const rodfit_status s = rodfit_get_tool_force(rt, rng() % 4 ? f : nullptr, t);
          Judge(&tally, "get_tool_force", s, rodfit_last_error(rt), Finite(t, 3));
          break;
        }
        case 8: {
          double pot = 0.0, kin = 0.0;
          const rodfit_status s = rodfit_get_energy(rt, &pot, rng() % 4 ? &kin : nullptr);
          Judge(&tally, "get_energy", s, rodfit_last_error(rt), std::isfinite(pot) && std::isfinite(kin));
          break;
        }
        case 9: {
          int nv = 0, nt = 0;
          const rodfit_status s = rodfit_get_mesh(rt, &nv, &nt, nullptr, 0, nullptr, 0);
          Judge(&tally, "get_mesh counts", s, rodfit_last_error(rt), nv > 0 && nt > 0);
          break;
        }
        case 10: {
          // The rest shape's knots (the suture has none): the count alone, or buffers that may be
          // null (some of them) or of a hostile capacity.
          double knot[4][2] = {{0, 0}, {0, 0}, {0, 0}, {0, 0}};
          double* buffer[4] = {knot[0], knot[1], knot[2], knot[3]};
          const int pattern = static_cast<int>(rng() % 4);
          if (pattern == 0)
            for (double*& b : buffer) b = nullptr;       // the count only
          else if (pattern == 1)
            buffer[rng() % 4] = nullptr;                 // one null among the buffers
          const size_t capacity = rng() % 2 ? 2 : static_cast<size_t>(-1) - rng() % 3;
          int count = -1;
          const rodfit_status s = rodfit_get_rest_knots(rt, rng() % 4 ? &count : nullptr,
                                                        buffer[0], buffer[1], buffer[2],
                                                        buffer[3], capacity);
          Judge(&tally, "get_rest_knots", s, rodfit_last_error(rt),
                count <= 2 && Finite(&knot[0][0], 8));
          break;
        }
        case 11: {
          if (rng() % 2) {
            const size_t capacity = rng() % 3 == 0 ? shape.size() - 1 : shape.size();
            double* buffer = rng() % 5 == 0 ? nullptr : shape.data();
            const rodfit_status s = rodfit_get_rest_shape(rt, buffer, capacity);
            Judge(&tally, "get_rest_shape", s, rodfit_last_error(rt),
                  buffer && Finite(buffer, capacity));
          } else {
            double k[3] = {0, 0, 0};
            const rodfit_status s = rodfit_get_rest_curvature(rt, rng() % 5 ? k : nullptr);
            Judge(&tally, "get_rest_curvature", s, rodfit_last_error(rt), Finite(k, 3));
          }
          break;
        }
      }
    }
    // Calls on a null handle: a status, never a crash.
    const double zero[3] = {0, 0, 0};
    Judge(&tally, "null step", rodfit_step(nullptr, nullptr), nullptr, true);
    Judge(&tally, "null set_tool_position", rodfit_set_tool_position(nullptr, zero), nullptr, true);
    Judge(&tally, "null get_rest_knots",
          rodfit_get_rest_knots(nullptr, nullptr, nullptr, nullptr, nullptr, nullptr, 0), nullptr,
          true);
    Judge(&tally, "null get_rest_shape", rodfit_get_rest_shape(nullptr, nullptr, 0), nullptr, true);
    EXPECT_EQ(rodfit_num_vertices(nullptr), 0);
    rodfit_destroy(rt);
  }
  rodfit_destroy(nullptr);
  std::printf("C API corpus: %d sequences (%d created), %d calls: success %d, clean error %d, "
              "silent %d, unknown status %d, crash 0\n",
              sequences, created, tally.calls, tally.ok, tally.clean_error, tally.silent,
              tally.bad_status);
  for (const auto& [call, count] : tally.silent_by_call)
    std::printf("  silent: %s x %d\n", call.c_str(), count);
  EXPECT_EQ(tally.silent, 0);
  EXPECT_EQ(tally.bad_status, 0);
  EXPECT_GT(created, kSequences / 4);
}

}  // namespace
