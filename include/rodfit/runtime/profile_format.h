// The profile JSON's keys, declared once (docs/formats.md, "Profile JSON"). The fit's writer
// (io/profile.cc) and the validating reader a simulator links (runtime/profile.cc) both go
// through these: the blocks that describe the model (the rod, its held ends, the spring zones,
// the section) are Visit functions over an archive that either writes each value or reads and
// checks it, and the other keys are named here. A key spelled in two files, or a writer and a
// reader that drift apart, is what this header rules out.
//
// An archive A (ProfileWriter in io, ProfileReader in runtime) provides, for a key of the
// current object (it keeps the dotted path for messages):
//   bool reading() const;
//   void Number(const char* key, double* v, Bound bound, Need need = kRequired);
//   void Integer(const char* key, int* v, int lo, int hi);
//   void Vector(const char* key, Vec3* v, Need need = kRequired);   // written always
//   void Direction(const char* key, Vec3* v);                       // not zero
//   void OptionalDirection(const char* key, std::optional<Vec3>* v);
//   void OptionalVector(const char* key, std::optional<Vec3>* v);
//   void Text(const char* key, std::string* v, Need need = kRequired);   // written when not empty
//   void NumberList(const char* key, std::vector<double>* v);       // optional; written when not empty
//   template <class T, class F> void List(const char* key, std::vector<T>* v, F visit);  // optional
//   template <class F> void Object(const char* key, F visit);       // required
//   template <class T, class F> void OptionalObject(const char* key, std::optional<T>* v, F visit);
//   void Check(bool ok, const char* key, const std::string& message);  // reading: fails at key
// where visit(A&, T&) or visit(A&) visits the object's keys. Reading, an object holding a key its
// visit does not declare is an error ("unknown key").
#pragma once

#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "rodfit/model/rod_radius.h"
#include "rodfit/model/scene.h"

namespace rodfit::profile_format {

enum Bound { kAnyNumber, kPositive, kNonNegative };
enum Need { kRequired, kOptional };

/// The document's `format` and the values of its `version` a reader accepts.
inline constexpr char kFormatName[] = "rodfit-profile";

// Top-level keys.
inline constexpr char kFormat[] = "format";
inline constexpr char kVersion[] = "version";
inline constexpr char kRodfitVersion[] = "rodfit_version";
inline constexpr char kRod[] = "rod";
inline constexpr char kGravity[] = "gravity";
inline constexpr char kHeld[] = "held";
inline constexpr char kSprings[] = "springs";
inline constexpr char kSection[] = "section";
inline constexpr char kParameters[] = "parameters";
inline constexpr char kDerived[] = "derived";
inline constexpr char kFit[] = "fit";
/// The document's keys, in the order the format lists them: the reader's allowed keys, and
/// every key the writer writes at the top (`section` only with one).
inline constexpr const char* kDocumentKeys[] = {kFormat,  kVersion,   kRodfitVersion, kRod,
                                                kGravity, kHeld,      kSprings,       kSection,
                                                kParameters, kDerived, kFit};

// The keys of one entry of `parameters` (a Parameter, rodfit/model/material_parameters.h).
inline constexpr char kValue[] = "value";
inline constexpr char kStd[] = "std";
inline constexpr char kFitted[] = "fitted";
inline constexpr char kIdentifiable[] = "identifiable";
inline constexpr char kUnit[] = "unit";
inline constexpr char kStart[] = "start";
inline constexpr char kReason[] = "reason";
inline constexpr char kAtBound[] = "at_bound";
inline constexpr char kTiedTo[] = "tied_to";
inline constexpr const char* kParameterKeys[] = {kValue, kStd,    kFitted,  kIdentifiable, kUnit,
                                                  kStart, kReason, kAtBound, kTiedTo};

/// Limits the reader keeps to: the scene reader's rod.segments and section.nodes limits.
inline constexpr int kMaxSegments = 100000;
inline constexpr int kMinSectionNodes = 8;
inline constexpr int kMaxSectionNodes = 256;
/// Below this sine of the angle between a clamp's tangent and normal the frame is taken to be a
/// mistake (the scene reader's limit).
inline constexpr double kMinClampSine = 1e-3;

namespace internal {

inline std::string Show(double v) {
  char buffer[32];
  std::snprintf(buffer, sizeof(buffer), "%.10g", v);
  return buffer;
}

inline bool Parallel(const Vec3& tangent, const Vec3& normal) {
  return tangent.cross(normal).norm() < kMinClampSine * tangent.norm() * normal.norm();
}

}  // namespace internal

/// `rod.rest_shape`: the rod's natural shape as the intrinsic curvature at knots along it
/// (RodSpec::rest_curvature_s / rest_curvature_profile: linear between knots, constant beyond,
/// added to `rest_curvature`), from `rod.rest_shape: FILE` of a scene or fitted by
/// `rollout --fit rest_curvature`. The keys are those of motion_fit.json's `rest_shape` block.
inline constexpr char kRestShape[] = "rest_shape";
inline constexpr char kRestShapeS[] = "s_m";          // [m] the knots' arc lengths
inline constexpr char kRestShapeK1[] = "k1_per_m";    // [1/m] k1° at each knot
inline constexpr char kRestShapeK2[] = "k2_per_m";    // [1/m] k2°
inline constexpr char kRestShapeTau[] = "tau_per_m";  // [1/m] tau° (rest twist)
/// A rest curvature whose turn over one segment, |kappa°| L / segments, exceeds this (a quarter
/// of a turn at a vertex, 2 tan(pi/4)) is refused: the discrete rod cannot hold it faithfully.
inline constexpr double kMaxRestTurnPerSegment = 2.0;

/// The knots of `rod.rest_shape` as the profile lists them.
struct RestShapeKnots {
  std::vector<double> s, k1, k2, tau;
};

/// `rod.rest_shape`: one entry per knot in each list (at least one), the arc lengths increasing
/// strictly within [0, length], every curvature finite (the reader's numbers) and within
/// kMaxRestTurnPerSegment per segment.
template <class A>
void VisitRestShape(A& a, RestShapeKnots& k, double length, int segments) {
  a.NumberList(kRestShapeS, &k.s);
  a.NumberList(kRestShapeK1, &k.k1);
  a.NumberList(kRestShapeK2, &k.k2);
  a.NumberList(kRestShapeTau, &k.tau);
  if (!a.reading()) return;
  const size_t n = k.s.size();
  a.Check(n >= 1, kRestShapeS, "must list the knots' arc lengths (at least one)");
  for (const char* key : {kRestShapeK1, kRestShapeK2, kRestShapeTau}) {
    const std::vector<double>& v =
        key == kRestShapeK1 ? k.k1 : key == kRestShapeK2 ? k.k2 : k.tau;
    a.Check(v.size() == n, key,
            "must have one entry per knot of s_m (" + std::to_string(n) + "; has " +
                std::to_string(v.size()) + ")");
  }
  if (k.k1.size() != n || k.k2.size() != n || k.tau.size() != n) return;
  for (size_t j = 0; j < n; ++j) {
    const std::string at = std::string(kRestShapeS) + "[" + std::to_string(j) + "]";
    a.Check(k.s[j] >= 0.0 && k.s[j] <= length, at.c_str(),
            "must lie in [0, rod.length = " + internal::Show(length) + "] (is " +
                internal::Show(k.s[j]) + ")");
    a.Check(j == 0 || k.s[j] > k.s[j - 1], at.c_str(), "must increase strictly");
    const double turn = std::sqrt(k.k1[j] * k.k1[j] + k.k2[j] * k.k2[j] + k.tau[j] * k.tau[j]) *
                        length / segments;
    a.Check(turn <= kMaxRestTurnPerSegment, (std::string(kRestShapeK1) + "[" + std::to_string(j) + "]").c_str(),
            "the rest curvature at this knot turns the rod by " + internal::Show(turn) +
                " per segment (at most " + internal::Show(kMaxRestTurnPerSegment) +
                "): more segments, or a curvature in 1/m?");
  }
}

/// `rod`: length [m], segments, radius [m] (0: the fit had none), linear_density [kg/m],
/// rest_curvature [1/m], rest_shape (VisitRestShape; written when the rod has one), and
/// vertex_s [m] when the rod's vertices are not evenly spaced.
template <class A>
void VisitRod(A& a, RodSpec& rod) {
  a.Number("length", &rod.length, kPositive);
  a.Integer("segments", &rod.segments, 2, kMaxSegments);
  a.Number("radius", &rod.radius, kNonNegative);
  if (a.reading() && rod.radius != 0.0) a.Check(CheckRodRadius(rod.radius, rod.length).empty(),
                                                "radius", CheckRodRadius(rod.radius, rod.length));
  a.Number("linear_density", &rod.linear_density, kNonNegative);
  a.Vector("rest_curvature", &rod.rest_curvature, kOptional);
  std::optional<RestShapeKnots> rest;
  if (!rod.rest_curvature_s.empty()) {  // writing (a reader's rod starts without one)
    RestShapeKnots k;
    k.s = rod.rest_curvature_s;
    for (const Vec3& c : rod.rest_curvature_profile)
      k.k1.push_back(c[0]), k.k2.push_back(c[1]), k.tau.push_back(c[2]);
    rest = k;
  }
  const double length = rod.length;
  const int segments = rod.segments;
  a.OptionalObject(kRestShape, &rest, [&](A& o, RestShapeKnots& k) {
    VisitRestShape(o, k, length, segments);
  });
  if (a.reading() && rest && rest->s.size() == rest->k1.size() &&
      rest->s.size() == rest->k2.size() && rest->s.size() == rest->tau.size()) {
    rod.rest_curvature_s = rest->s;
    rod.rest_curvature_profile.clear();
    for (size_t j = 0; j < rest->s.size(); ++j)
      rod.rest_curvature_profile.push_back(Vec3(rest->k1[j], rest->k2[j], rest->tau[j]));
  }
  a.NumberList("vertex_s", &rod.vertex_s);
  if (!a.reading() || rod.vertex_s.empty()) return;
  const std::vector<double>& s = rod.vertex_s;
  a.Check(static_cast<int>(s.size()) == rod.segments + 1, "vertex_s",
          "must have segments + 1 = " + std::to_string(rod.segments + 1) + " values (has " +
              std::to_string(s.size()) + ")");
  for (size_t i = 0; i < s.size(); ++i)
    a.Check(i == 0 ? s[i] == 0.0 : s[i] > s[i - 1],
            ("vertex_s[" + std::to_string(i) + "]").c_str(), "must increase strictly from 0");
  a.Check(std::abs(s.back() - rod.length) <= 1e-12 * rod.length, "vertex_s",
          "must end at rod.length (" + internal::Show(rod.length) + ")");
}

/// An arc length of the rod, in [0, length].
template <class A>
void VisitArcLength(A& a, const char* key, double* s, double length) {
  a.Number(key, s, kAnyNumber);
  a.Check(*s >= 0.0 && *s <= length, key,
          "must lie in [0, rod.length = " + internal::Show(length) + "] (is " +
              internal::Show(*s) + ")");
}

/// `from`, `to`: a stretch of the rod [m], from < to.
template <class A>
void VisitInterval(A& a, Interval& in, double length) {
  VisitArcLength(a, "from", &in.from, length);
  VisitArcLength(a, "to", &in.to, length);
  a.Check(in.from < in.to, "to", "must be greater than from (" + internal::Show(in.from) + ")");
}

/// `held`: the rod's held boundary as mounted (the first case's clamp, end clamp or end pin,
/// interior pins and cuts; the instruments of a case are the simulator's tools).
template <class A>
void VisitHeld(A& a, LoadCase& c, double length) {
  a.Text("case", &c.name, kOptional);
  a.Object("clamp", [&](A& o) {
    o.Vector("position", &c.clamp.position);
    o.Direction("tangent", &c.clamp.tangent);
    o.Direction("normal", &c.clamp.normal);
    o.Check(!internal::Parallel(c.clamp.tangent, c.clamp.normal), "normal",
            "is (nearly) parallel to the tangent");
  });
  a.OptionalObject("end_clamp", &c.end_clamp, [&](A& o, EndClamp& e) {
    o.Vector("position", &e.position);
    o.Direction("tangent", &e.tangent);
    o.OptionalDirection("normal", &e.normal);
    o.Check(!e.normal || !internal::Parallel(e.tangent, *e.normal), "normal",
            "is (nearly) parallel to the tangent");
  });
  a.OptionalVector("end_pin", &c.end_pin);
  a.Check(!(c.end_clamp && c.end_pin), "end_pin",
          "a rod has an end clamp or an end pin, not both");
  a.List("pins", &c.pins, [&](A& o, Pin& pin) {
    VisitArcLength(o, "s", &pin.s, length);
    o.Check(pin.s > 0.0 && pin.s < length, "s", "must lie inside (0, rod.length)");
    o.Vector("position", &pin.position);
  });
  a.List("cuts", &c.cuts, [&](A& o, Interval& cut) { VisitInterval(o, cut, length); });
}

/// One spring zone of `springs`: from, to [m] and its own parameter's name (absent: the
/// material's spring_stiffness).
template <class A>
void VisitSpringZone(A& a, SpringZone& zone, double length) {
  Interval in{zone.from, zone.to};
  VisitInterval(a, in, length);
  zone.from = in.from;
  zone.to = in.to;
  a.Text("parameter", &zone.parameter, kOptional);
}

/// `section`: the cross-section ring (radius [m], nodes, h_factor, stop_factor).
template <class A>
void VisitSection(A& a, SectionSpec& s) {
  a.Number("radius", &s.radius, kPositive);
  a.Integer("nodes", &s.nodes, kMinSectionNodes, kMaxSectionNodes);
  a.Number("h_factor", &s.h_factor, kPositive, kOptional);
  a.Number("stop_factor", &s.stop_factor, kPositive, kOptional);
}

}  // namespace rodfit::profile_format
