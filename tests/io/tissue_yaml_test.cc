// The tissue keys of the experiment YAML: section, poke and the ring parameters; each
// mistake is an InputError naming the file, the line and the key.
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "rodfit/io/errors.h"
#include "rodfit/io/experiment.h"
#include "rodfit/pipeline/experiment.h"

namespace rodfit {
namespace {

using ::testing::HasSubstr;

const char* kHead = R"(rod: {length: 0.15, segments: 30, radius: 0.012, linear_density: 0.45}
parameters:
  bend_stiffness: {value: 2.0e-4}
  twist_stiffness: {value: 1.5e-4}
  stretch_stiffness: {value: 40}
)";

std::string ErrorOf(const std::string& text) {
  try {
    ParseExperiment(text, "tissue.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(TissueYaml, PokeWithSectionAndRingParameters) {
  const Experiment e = ParseExperiment(std::string(kHead) + R"(  ring_bend_stiffness: {value: 2.0e-5, fit: true}
  ring_stretch_stiffness: {value: 5}
section: {radius: 0.012, nodes: 24, h_factor: 0.4, stop_factor: 0.005}
cases:
  - name: poked
    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
    poke: {s: 0.075, force: [0, -0.02, 0]}
)",
                                       "tissue.yaml");
  ASSERT_TRUE(e.scene.section.has_value());
  EXPECT_EQ(e.scene.section->nodes, 24);
  EXPECT_DOUBLE_EQ(e.scene.section->h_factor, 0.4);
  EXPECT_DOUBLE_EQ(e.scene.material.ring_bend_stiffness, 2.0e-5);
  EXPECT_TRUE(e.parameters.at("ring_bend_stiffness").fit);
  ASSERT_TRUE(e.scene.cases[0].poke.has_value());
  EXPECT_DOUBLE_EQ(e.scene.cases[0].poke->force.y(), -0.02);
}

TEST(TissueYaml, PokeWithoutASectionIsAnError) {
  const std::string err = ErrorOf(std::string(kHead) + R"(cases:
  - name: poked
    clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
    poke: {s: 0.075, force: [0, -0.02, 0]}
)");
  EXPECT_THAT(err, HasSubstr("tissue.yaml:9: cases[0].poke"));
  EXPECT_THAT(err, HasSubstr("section"));
}

TEST(TissueYaml, SectionNeedsTheRingParameters) {
  const std::string err = ErrorOf(std::string(kHead) + R"(section: {radius: 0.012}
cases:
  - clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
)");
  EXPECT_THAT(err, HasSubstr("parameters.ring_bend_stiffness"));
  EXPECT_THAT(err, HasSubstr("missing required key"));
}

TEST(TissueYaml, BadSectionAndPokeValues) {
  const std::string ring = R"(  ring_bend_stiffness: {value: 2.0e-5}
  ring_stretch_stiffness: {value: 5}
)";
  EXPECT_THAT(ErrorOf(std::string(kHead) + ring + R"(section: {radius: 0.012, nodes: 4}
cases:
  - clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
)"),
              HasSubstr("tissue.yaml:8: section.nodes: must be an integer in [8, 256]"));
  EXPECT_THAT(ErrorOf(std::string(kHead) + ring + R"(section: {radius: 0.012}
cases:
  - clamp: {position: [0, 0, 0], tangent: [1, 0, 0], normal: [0, 0, 1]}
    poke: {s: 0.2, force: [0, -0.02, 0]}
)"),
              HasSubstr("cases[0].poke.s: must be in [0, 0.15]"));
}

}  // namespace
}  // namespace rodfit
