// The C interface (rodfit/runtime/rodfit_c.h): status codes and messages for every failure, no
// exception across it, and the same numbers as the C++ runtime.
#include <cmath>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "rodfit/runtime/profile.h"
#include "rodfit/runtime/rodfit_c.h"
#include "rodfit/runtime/runtime.h"

namespace {

using ::testing::HasSubstr;

const std::string kSuture = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/suture.json";

TEST(CApi, CreateFailuresAreCodesWithMessages) {
  rodfit_options options;
  rodfit_default_options(&options);
  options.tool_s = 0.2;
  char error[256];
  rodfit_runtime* rt = reinterpret_cast<rodfit_runtime*>(0x1);
  EXPECT_EQ(rodfit_create("/no/such/profile.json", &options, nullptr, nullptr, 0, &rt, error,
                          sizeof(error)),
            RODFIT_PROFILE_ERROR);
  EXPECT_EQ(rt, nullptr);
  EXPECT_THAT(error, HasSubstr("/no/such/profile.json: cannot read the file"));
  EXPECT_EQ(rodfit_create(nullptr, &options, nullptr, nullptr, 0, &rt, error, sizeof(error)),
            RODFIT_INVALID_ARGUMENT);
  options.tool_s = -1.0;
  EXPECT_EQ(rodfit_create(kSuture.c_str(), &options, nullptr, nullptr, 0, &rt, error, sizeof(error)),
            RODFIT_INVALID_ARGUMENT);
  EXPECT_THAT(error, HasSubstr("tool_s"));
  options.tool_s = 0.2;
  const char* names[] = {"bend_stiffness"};
  const double values[] = {-1.0};
  EXPECT_EQ(rodfit_create(kSuture.c_str(), &options, names, values, 1, &rt, error, sizeof(error)),
            RODFIT_PROFILE_ERROR);
  EXPECT_THAT(error, HasSubstr("parameters.bend_stiffness.value (--set bend_stiffness): must be > 0"));
  // A message longer than the buffer is cut, still terminated.
  char tiny[8];
  EXPECT_EQ(rodfit_create("/no/such/profile.json", &options, nullptr, nullptr, 0, &rt, tiny,
                          sizeof(tiny)),
            RODFIT_PROFILE_ERROR);
  EXPECT_EQ(std::string(tiny).size(), 7u);
}

TEST(CApi, LoopMatchesTheCppRuntime) {
  rodfit_options options;
  rodfit_default_options(&options);
  options.tool_s = 0.2;
  char error[256];
  rodfit_runtime* rt = nullptr;
  ASSERT_EQ(rodfit_create(kSuture.c_str(), &options, nullptr, nullptr, 0, &rt, error, sizeof(error)),
            RODFIT_OK)
      << error;
  rodfit::RuntimeOptions cpp_options;
  cpp_options.tool_s = 0.2;
  rodfit::Runtime cpp(rodfit::LoadProfile(kSuture), cpp_options);

  const int n = rodfit_num_vertices(rt);
  ASSERT_EQ(n, cpp.model().num_vertices());
  std::vector<double> shape(3 * n);
  ASSERT_EQ(rodfit_get_shape(rt, shape.data(), shape.size()), RODFIT_OK);
  const double home[3] = {shape[3 * (n - 1)], shape[3 * (n - 1) + 1], shape[3 * (n - 1) + 2]};
  for (int k = 1; k <= 20; ++k) {
    const double tool[3] = {home[0] - 1e-4 * k, home[1] + 5e-5 * k, home[2]};
    ASSERT_EQ(rodfit_set_tool_position(rt, tool), RODFIT_OK);
    cpp.SetToolPosition(rodfit::Vec3(tool[0], tool[1], tool[2]));
    rodfit_step_info info;
    ASSERT_EQ(rodfit_step(rt, &info), RODFIT_OK) << rodfit_last_error(rt);
    ASSERT_TRUE(cpp.Step().ok());
  }
  ASSERT_EQ(rodfit_get_shape(rt, shape.data(), shape.size()), RODFIT_OK);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(shape[3 * i + c], cpp.Shape()(c, i));
  double force[3], torque[3];
  ASSERT_EQ(rodfit_get_tool_force(rt, force, torque), RODFIT_OK);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(force[c], cpp.ToolForce()[c]);
    EXPECT_EQ(torque[c], 0.0);
  }
  int nv = 0, nt = 0;
  ASSERT_EQ(rodfit_get_mesh(rt, &nv, &nt, nullptr, 0, nullptr, 0), RODFIT_OK);
  EXPECT_EQ(nv, n * options.mesh_ring_vertices);
  std::vector<double> vertices(3 * nv);
  std::vector<int> triangles(3 * nt);
  EXPECT_EQ(rodfit_get_mesh(rt, &nv, &nt, vertices.data(), vertices.size(), triangles.data(),
                            triangles.size()),
            RODFIT_OK);

  // Misuse: codes and the handle's message, the runtime still usable.
  EXPECT_EQ(rodfit_get_shape(rt, shape.data(), 3), RODFIT_INVALID_ARGUMENT);
  EXPECT_THAT(rodfit_last_error(rt), HasSubstr("too small"));
  EXPECT_EQ(rodfit_set_tool_position(rt, nullptr), RODFIT_INVALID_ARGUMENT);
  const double nan_tool[3] = {std::nan(""), 0.0, 0.0};
  ASSERT_EQ(rodfit_set_tool_position(rt, nan_tool), RODFIT_OK);
  EXPECT_EQ(rodfit_step(rt, nullptr), RODFIT_TOOL_REFUSED);
  EXPECT_THAT(rodfit_last_error(rt), HasSubstr("last good state kept"));
  EXPECT_THAT(rodfit_last_error(rt), HasSubstr("tool position x = nan is not finite"));
  EXPECT_EQ(rodfit_step(nullptr, nullptr), RODFIT_INVALID_ARGUMENT);
  EXPECT_STREQ(rodfit_status_name(RODFIT_TIME_BUDGET), "RODFIT_TIME_BUDGET");
  rodfit_destroy(rt);
  rodfit_destroy(nullptr);
}

// The oriented grasp through C: the same torque as the C++ runtime after the same turn.
TEST(CApi, OrientedGraspMatchesTheCppRuntime) {
  const std::string bowel = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/bowel_drag.json";
  rodfit_options options;
  rodfit_default_options(&options);
  options.tool_s = 0.1;
  options.hold_orientation = 1;
  rodfit_runtime* rt = nullptr;
  ASSERT_EQ(rodfit_create(bowel.c_str(), &options, nullptr, nullptr, 0, &rt, nullptr, 0),
            RODFIT_OK);
  rodfit::RuntimeOptions cpp_options;
  cpp_options.tool_s = 0.1;
  cpp_options.hold_orientation = true;
  rodfit::Runtime cpp(rodfit::LoadProfile(bowel), cpp_options);
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(0.1, rodfit::Vec3::UnitY()).toRotationMatrix();
  double rotation[9];
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) rotation[3 * r + c] = turn(r, c);
  ASSERT_EQ(rodfit_set_tool_orientation(rt, rotation), RODFIT_OK);
  cpp.SetToolOrientation(turn);
  ASSERT_EQ(rodfit_step(rt, nullptr), RODFIT_OK) << rodfit_last_error(rt);
  ASSERT_TRUE(cpp.Step().ok());
  double force[3], torque[3];
  ASSERT_EQ(rodfit_get_tool_force(rt, force, torque), RODFIT_OK);
  EXPECT_GT(cpp.ToolTorque().norm(), 0.0);
  for (int c = 0; c < 3; ++c) {
    EXPECT_EQ(force[c], cpp.ToolForce()[c]);
    EXPECT_EQ(torque[c], cpp.ToolTorque()[c]);
  }
  EXPECT_EQ(rodfit_set_tool_orientation(rt, nullptr), RODFIT_INVALID_ARGUMENT);
  rodfit_destroy(rt);
}

// A dynamic poke through C: mode and tool selected by the options, the same shape, force and
// dented mesh as the C++ runtime tick for tick.
TEST(CApi, DynamicPokeMatchesTheCppRuntime) {
  const std::string bowel = std::string(RODFIT_SOURCE_DIR) + "/data/profiles/bowel_poke.json";
  rodfit_options options;
  rodfit_default_options(&options);
  options.mode = RODFIT_MODE_DYNAMIC;
  options.tool = RODFIT_TOOL_POKE;
  options.tool_s = 0.075;
  rodfit_runtime* rt = nullptr;
  char error[256];
  ASSERT_EQ(rodfit_create(bowel.c_str(), &options, nullptr, nullptr, 0, &rt, error, sizeof(error)),
            RODFIT_OK)
      << error;
  rodfit::RuntimeOptions cpp_options;
  cpp_options.mode = rodfit::RuntimeMode::kDynamic;
  cpp_options.tool = rodfit::ToolKind::kPoke;
  cpp_options.tool_s = 0.075;
  rodfit::Runtime cpp(rodfit::LoadProfile(bowel), cpp_options);
  for (int k = 1; k <= 20; ++k) {
    const double push[3] = {0.0, -1e-3 * k, -5e-4 * k};
    ASSERT_EQ(rodfit_set_tool_force(rt, push), RODFIT_OK);
    cpp.SetToolForce(rodfit::Vec3(push[0], push[1], push[2]));
    ASSERT_EQ(rodfit_step(rt, nullptr), RODFIT_OK) << rodfit_last_error(rt);
    ASSERT_TRUE(cpp.Step().ok());
  }
  const int n = rodfit_num_vertices(rt);
  std::vector<double> shape(3 * n);
  ASSERT_EQ(rodfit_get_shape(rt, shape.data(), shape.size()), RODFIT_OK);
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(shape[3 * i + c], cpp.Shape()(c, i));
  EXPECT_GT((cpp.Shape() - rodfit::Runtime(rodfit::LoadProfile(bowel), cpp_options).Shape())
                .cwiseAbs()
                .maxCoeff(),
            0.0);  // the push moved the rod
  double force[3];
  ASSERT_EQ(rodfit_get_tool_force(rt, force, nullptr), RODFIT_OK);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(force[c], cpp.ToolForce()[c]);
  EXPECT_EQ(force[1], 2e-2);  // minus the last push
  int nv = 0, nt = 0;
  ASSERT_EQ(rodfit_get_mesh(rt, &nv, &nt, nullptr, 0, nullptr, 0), RODFIT_OK);
  std::vector<double> vertices(3 * nv);
  std::vector<int> triangles(3 * nt);
  ASSERT_EQ(rodfit_get_mesh(rt, &nv, &nt, vertices.data(), vertices.size(), triangles.data(),
                            triangles.size()),
            RODFIT_OK);
  rodfit::TubeMesh mesh;
  cpp.Mesh(&mesh);
  ASSERT_EQ(mesh.num_vertices(), nv);
  for (int i = 0; i < nv; ++i)
    for (int c = 0; c < 3; ++c) EXPECT_EQ(vertices[3 * i + c], mesh.vertices(c, i));
  rodfit_destroy(rt);
}

}  // namespace
