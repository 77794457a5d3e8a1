// The fit's one list of measurements (rodfit/fit/measurement.h): every kind in residual order,
// with its counts, unit and loss rows; force readings evaluated against given reactions and
// their derivatives; surface points against a given ring, the Jacobian by finite differences of
// the ring; the misfit summaries in measurement units.
#include "rodfit/fit/measurement.h"

#include <cmath>

#include <gtest/gtest.h>

namespace rodfit {
namespace {

ForceMeasurement Reading(const std::string& observation, const std::string& point, Vec3 force,
                         double sigma) {
  ForceMeasurement f;
  f.label = observation + " #" + point;
  f.point = point;
  f.force = force;
  f.sigma = sigma;
  return f;
}

// Four vertices on x; markers at both ends; two force entries (the first with a moment reading
// on the clamp) and one surface point set.
MeasurementList MixedCase() {
  MeasurementList list;
  const std::vector<double> s = {0.0, 1.0, 2.0, 3.0};
  list.push_back(MakeShapeMeasurement(
      "markers3d", "markers3d m.csv",
      Markers3dObservation(s, std::vector<Marker3d>{{0.0, Vec3(0, 0, 0)}, {3.0, Vec3(3, 0, 0.1)}},
                           0.01)));
  ForceMeasurement clamp = Reading("reaction clamp.csv", "clamp", Vec3(1, 0, 0), 0.5);
  clamp.moment = Vec3(0, 0.2, 0);
  clamp.sigma_moment = 0.1;
  list.push_back(std::make_shared<ForceReadings>("reaction", "reaction clamp.csv",
                                                 std::vector<ForceMeasurement>{clamp}));
  list.push_back(std::make_shared<ForceReadings>(
      "grasp_force", "grasp_force log.csv",
      std::vector<ForceMeasurement>{Reading("grasp_force log.csv", "grasp", Vec3(0, 2, 0), 0.25),
                                    Reading("grasp_force log.csv", "grasp", Vec3(0, 1, 0), 0.25)}));
  // A vertex foot, an edge foot.
  list.push_back(std::make_shared<SurfacePointSet>(
      "surface_points", "surface_points dent.csv",
      std::vector<Vec3>{Vec3(0.0, 1.2, 0.0), Vec3(0.0, 0.1, 0.7)}, 0.1));
  return list;
}

TEST(CaseMeasurementsTest, EveryKindInResidualOrderWithItsCounts) {
  const MeasurementList list = MixedCase();
  ASSERT_EQ(list.size(), 4u);
  EXPECT_EQ(list[0]->type(), "markers3d");
  EXPECT_EQ(list[0]->label(), "markers3d m.csv");
  EXPECT_STREQ(list[0]->unit(), "m");
  EXPECT_EQ(list[0]->num_measurements(), 2);
  EXPECT_EQ(list[0]->num_residuals(), 6);
  EXPECT_EQ(list[0]->num_noise_residuals(), 6);
  EXPECT_EQ(list[0]->measurement_rows(1), 3);

  EXPECT_EQ(list[1]->type(), "reaction");
  EXPECT_EQ(list[1]->label(), "reaction clamp.csv");
  EXPECT_STREQ(list[1]->unit(), "N");
  EXPECT_EQ(list[1]->num_measurements(), 1);
  EXPECT_EQ(list[1]->num_residuals(), 6);  // force and moment
  EXPECT_EQ(list[1]->measurement_rows(0), 6);
  EXPECT_TRUE(list[1]->needs_reactions());

  // Consecutive readings of one entry are one measurement list.
  EXPECT_EQ(list[2]->label(), "grasp_force log.csv");
  EXPECT_EQ(list[2]->num_measurements(), 2);
  EXPECT_EQ(list[2]->num_residuals(), 6);
  EXPECT_EQ(list[2]->num_noise_residuals(), 6);

  // A surface point carries noise across the ring only: 2 of its 3 residuals.
  EXPECT_EQ(list[3]->type(), "surface_points");
  EXPECT_STREQ(list[3]->unit(), "m");
  EXPECT_EQ(list[3]->num_residuals(), 6);
  EXPECT_EQ(list[3]->num_noise_residuals(), 4);
  EXPECT_TRUE(list[3]->needs_section());
  EXPECT_FALSE(list[3]->needs_reactions());
}

TEST(CaseMeasurementsTest, ForceReadingsAgainstTheReactionsAndTheirDerivatives) {
  const MeasurementList list = MixedCase();
  std::vector<HeldReaction> reactions(2);
  reactions[0].point = "clamp";
  reactions[0].force = Vec3(1.5, 0, 0);
  reactions[0].moment = Vec3(0, 0.1, 0.05);
  reactions[1].point = "grasp";
  reactions[1].force = Vec3(0, 1.5, 0.5);
  std::vector<Eigen::Matrix<double, 6, Eigen::Dynamic>> d_reactions(2);
  d_reactions[0] = Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, 2);
  d_reactions[1] = Eigen::Matrix<double, 6, Eigen::Dynamic>::Zero(6, 2);
  for (int i = 0; i < 6; ++i) {
    d_reactions[0](i, 0) = 1.0 + i;
    d_reactions[1](i, 1) = 10.0 + i;
  }
  RodState state;
  SolvedCase solved;
  solved.state = &state;
  solved.reactions = &reactions;
  solved.num_parameters = 2;
  solved.d_reactions = &d_reactions;

  double r[6], J[12];
  std::string why;
  ASSERT_TRUE(list[1]->Evaluate(solved, r, J, &why)) << why;
  EXPECT_DOUBLE_EQ(r[0], (1.5 - 1.0) / 0.5);
  EXPECT_DOUBLE_EQ(r[4], (0.1 - 0.2) / 0.1);
  EXPECT_DOUBLE_EQ(r[5], 0.05 / 0.1);
  EXPECT_DOUBLE_EQ(J[0 * 2 + 0], 1.0 / 0.5);
  EXPECT_DOUBLE_EQ(J[4 * 2 + 0], 5.0 / 0.1);
  EXPECT_DOUBLE_EQ(J[4 * 2 + 1], 0.0);

  ASSERT_TRUE(list[2]->Evaluate(solved, r, J, &why)) << why;
  EXPECT_DOUBLE_EQ(r[1], (1.5 - 2.0) / 0.25);  // first reading, y
  EXPECT_DOUBLE_EQ(r[4], (1.5 - 1.0) / 0.25);  // second reading, y
  EXPECT_DOUBLE_EQ(r[5], 0.5 / 0.25);
  EXPECT_DOUBLE_EQ(J[3 * 2 + 1], 10.0 / 0.25);  // second reading's x row: d force_x
  EXPECT_DOUBLE_EQ(J[3 * 2 + 0], 0.0);

  ObservationFit fit;
  std::vector<MeasurementResidual> per;
  list[1]->Evaluate(solved, r, nullptr, &why);
  list[1]->Summarise(Mat3X(), r, &fit, &per);
  EXPECT_NEAR(fit.rms, 0.5, 1e-15);
  EXPECT_NEAR(fit.rms_moment, std::hypot(0.1, 0.05), 1e-15);
  ASSERT_EQ(per.size(), 2u);  // the force, then the moment
  EXPECT_EQ(per[1].unit, "N m");
  EXPECT_NEAR(per[1].error.z(), 0.05, 1e-15);

  // A reading at a point the case does not hold names it.
  reactions[1].point = "pins[0]";
  EXPECT_FALSE(list[2]->Evaluate(solved, r, nullptr, &why));
  EXPECT_NE(why.find("holds no grasp"), std::string::npos) << why;
}

// The surface residual's Jacobian is the foot's derivative as the ring moves: compare it with
// central differences of the residuals over a ring moved along the given node derivatives.
TEST(CaseMeasurementsTest, SurfacePointJacobianMatchesFiniteDifferences) {
  const MeasurementList list = MixedCase();
  const int nodes = 12;
  auto ring_at = [&](double t) {
    Eigen::Matrix3Xd ring(3, nodes);
    for (int k = 0; k < nodes; ++k) {
      const double a = 2.0 * M_PI * k / nodes;
      // An ellipse whose y semi-axis grows with t and whose centre moves in z.
      ring.col(k) = Vec3(0.0, (1.0 + 0.3 * t) * std::cos(a), 0.8 * std::sin(a) + 0.1 * t);
    }
    return ring;
  };
  PokeResult poke;
  poke.deformed_world = ring_at(0.0);
  std::vector<Eigen::Matrix3Xd> d_ring(1, Eigen::Matrix3Xd(3, nodes + 1));
  const Eigen::Matrix3Xd d_nodes = ring_at(1.0) - ring_at(0.0);  // linear in t
  d_ring[0].leftCols(nodes) = d_nodes;
  d_ring[0].col(nodes) = d_nodes.col(0);
  RodState state;
  SolvedCase solved;
  solved.state = &state;
  solved.poke = &poke;
  solved.num_parameters = 1;
  solved.d_ring = &d_ring;
  double r[6], J[6];
  std::string why;
  ASSERT_TRUE(list[3]->Evaluate(solved, r, J, &why)) << why;
  const double h = 1e-6;
  double rp[6], rm[6];
  poke.deformed_world = ring_at(h);
  ASSERT_TRUE(list[3]->Evaluate(solved, rp, nullptr, &why));
  poke.deformed_world = ring_at(-h);
  ASSERT_TRUE(list[3]->Evaluate(solved, rm, nullptr, &why));
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(J[i], (rp[i] - rm[i]) / (2 * h), 1e-6) << "row " << i;
  // Both points lie off the ring: the residuals are not zero, and the summary is in metres.
  ObservationFit fit;
  std::vector<MeasurementResidual> per;
  list[3]->Summarise(Mat3X(), r, &fit, &per);
  ASSERT_EQ(per.size(), 2u);
  EXPECT_GT(fit.rms, 0.0);
  EXPECT_NEAR(fit.rms, std::sqrt((per[0].error.squaredNorm() + per[1].error.squaredNorm()) / 2),
              1e-15);
}

}  // namespace
}  // namespace rodfit
