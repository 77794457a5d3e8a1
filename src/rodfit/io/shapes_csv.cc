// shapes.csv writing and reading (see shapes_csv.h).
#include "rodfit/io/shapes_csv.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <set>
#include <stdexcept>

#include "rodfit/io/csv.h"
#include "rodfit/io/errors.h"

namespace rodfit {

std::string FormatShapesCsv(const std::vector<CaseShape>& shapes) {
  std::string out = "case,vertex,s,x,y,z\n";
  for (const CaseShape& shape : shapes) {
    if (shape.x.cols() != static_cast<Eigen::Index>(shape.s.size())) {
      throw std::invalid_argument("FormatShapesCsv: shape.x.cols() == shape.s.size()");
    }
    for (size_t i = 0; i < shape.s.size(); ++i) {
      const auto col = static_cast<Eigen::Index>(i);
      out += shape.name + "," + std::to_string(i) + "," + FormatDouble(shape.s[i]) + "," +
             FormatDouble(shape.x(0, col)) + "," + FormatDouble(shape.x(1, col)) + "," +
             FormatDouble(shape.x(2, col)) + "\n";
    }
  }
  return out;
}

void WriteShapesCsv(const std::string& path, const std::vector<CaseShape>& shapes) {
  WriteFileAtomically(path, FormatShapesCsv(shapes));
}

std::vector<CaseShape> ReadShapesCsv(const std::string& path) {
  const CsvTable table = CsvTable::Read(path);
  const std::vector<std::string> names = table.TextColumn("case");
  const std::vector<double> vertex = table.Column("vertex");
  const std::vector<double> s = table.Column("s");
  const std::vector<double> x = table.Column("x");
  const std::vector<double> y = table.Column("y");
  const std::vector<double> z = table.Column("z");

  std::vector<CaseShape> shapes;
  std::set<std::string> seen;
  for (int r = 0; r < table.num_rows();) {
    int end = r;
    while (end < table.num_rows() && names[end] == names[r]) ++end;
    if (!seen.insert(names[r]).second) {
      throw InputError(path, table.line(r), "case", "rows of case " + ClipForMessage(names[r]) + " are split");
    }
    CaseShape shape;
    shape.name = names[r];
    shape.x.resize(3, end - r);
    for (int i = r; i < end; ++i) {
      if (vertex[i] != i - r) {
        throw InputError(path, table.line(i), "vertex",
                         "expected vertex " + std::to_string(i - r) + " of case " +
                             ClipForMessage(shape.name));
      }
      shape.s.push_back(s[i]);
      shape.x.col(i - r) << x[i], y[i], z[i];
    }
    shapes.push_back(shape);
    r = end;
  }
  return shapes;
}

std::string FormatForcesCsv(const std::vector<CaseForce>& forces) {
  std::string out = "case,point,s,x,y,z,fx,fy,fz,mx,my,mz\n";
  for (const CaseForce& f : forces) {
    out += f.name + "," + f.point + "," + FormatDouble(f.s);
    for (const Eigen::Vector3d* v : {&f.position, &f.force, &f.moment})
      for (int i = 0; i < 3; ++i) out += "," + FormatDouble((*v)[i]);
    out += "\n";
  }
  return out;
}

std::string FormatSummaryCsv(const std::vector<CaseSummaryRow>& rows) {
  // No wall time: the same scene gives the same bytes (docs/cli.md, "Reproducible outputs");
  // simulate prints its time.
  std::string out = "case,converged,stable,iterations,gradient_norm,reason\n";
  for (const CaseSummaryRow& r : rows) {
    std::string reason;
    for (char c : r.reason) reason += (c == '"') ? std::string("\"\"") : std::string(1, c);
    out += r.name + "," + (r.converged ? "1" : "0") + "," + (r.stable ? "1" : "0") + "," +
           std::to_string(r.iterations) + "," + FormatDouble(r.gradient_norm) + ",\"" + reason +
           "\"\n";
  }
  return out;
}

void WriteForcesCsv(const std::string& path, const std::vector<CaseForce>& forces) {
  WriteFileAtomically(path, FormatForcesCsv(forces));
}

std::string FormatSectionsCsv(const std::vector<CaseSection>& sections) {
  std::string out = "case,node,x0,y0,z0,x,y,z\n";
  for (const CaseSection& c : sections)
    for (int k = 0; k < c.rest.cols(); ++k) {
      out += c.name + "," + std::to_string(k);
      for (int i = 0; i < 3; ++i) out += "," + FormatDouble(c.rest(i, k));
      for (int i = 0; i < 3; ++i) out += "," + FormatDouble(c.deformed(i, k));
      out += "\n";
    }
  return out;
}

void WriteSectionsCsv(const std::string& path, const std::vector<CaseSection>& sections) {
  WriteFileAtomically(path, FormatSectionsCsv(sections));
}

}  // namespace rodfit

namespace rodfit {

std::string FormatTrajectoryCsv(const std::vector<CaseMotion>& motions) {
  std::string out = "case,t,vertex,s,x,y,z\n";
  for (const CaseMotion& m : motions) {
    for (const CaseMotion::Frame& f : m.frames) {
      const std::string head = m.name + "," + FormatDouble(f.t) + ",";
      for (Eigen::Index i = 0; i < f.x.cols(); ++i) {
        out += head + std::to_string(i) + "," + FormatDouble(m.s[i]) + "," +
               FormatDouble(f.x(0, i)) + "," + FormatDouble(f.x(1, i)) + "," +
               FormatDouble(f.x(2, i)) + "\n";
      }
    }
  }
  return out;
}

std::string FormatReactionsCsv(const std::vector<CaseMotion>& motions) {
  std::string out = "case,t,point,s,x,y,z,fx,fy,fz,mx,my,mz\n";
  auto v3 = [](const Eigen::Vector3d& v) {
    return FormatDouble(v[0]) + "," + FormatDouble(v[1]) + "," + FormatDouble(v[2]);
  };
  for (const CaseMotion& m : motions) {
    for (const CaseMotion::Frame& f : m.frames) {
      for (const CaseForce& r : f.reactions) {
        out += m.name + "," + FormatDouble(f.t) + "," + r.point + "," + FormatDouble(r.s) + "," +
               v3(r.position) + "," + v3(r.force) + "," + v3(r.moment) + "\n";
      }
    }
  }
  return out;
}

std::string FormatMotionSummaryCsv(const std::vector<MotionSummaryRow>& rows) {
  std::string out = "case,completed,steps,newton_iterations,stable_step,reason\n";
  for (const MotionSummaryRow& r : rows) {
    std::string reason;
    for (char c : r.reason) reason += (c == '"') ? std::string("\"\"") : std::string(1, c);
    out += r.name + "," + (r.completed ? "1" : "0") + "," + std::to_string(r.steps) + "," +
           std::to_string(r.newton_iterations) + "," + FormatDouble(r.stable_step) + ",\"" +
           reason + "\"\n";
  }
  return out;
}

MotionRunEstimate EstimateMotionRun(const Scene& scene, int markers) {
  MotionRunEstimate out;
  if (!scene.dynamics) return out;
  const DynamicsSpec& spec = *scene.dynamics;
  // Bytes of a written row: the case name and a comma, then its numbers at up to 24 characters.
  constexpr double kNumberBytes = 24.0;
  const double steps = std::ceil(spec.duration / spec.time_step);
  const double frames = std::floor(steps / std::max(1, spec.output_every)) + 2.0;
  const double vertices = scene.rod.segments + 1.0;
  for (const LoadCase& c : scene.cases) {
    const double name = c.name.size() + 1.0;
    const double held = 1.0 + c.pins.size() + (c.end_clamp || c.end_pin ? 1 : 0) + (c.grasp ? 1 : 0);
    out.vertex_steps += steps * vertices;
    out.output_bytes += frames * (vertices * (name + 6 * kNumberBytes) +
                                  held * (name + 14 * kNumberBytes) +
                                  markers * (name + 5 * kNumberBytes));
  }
  return out;
}

void CheckMotionRunSize(const MotionRunEstimate& estimate, const std::string& scene_path,
                        const std::string& option) {
  char text[400];
  if (estimate.vertex_steps > kMaxMotionVertexSteps) {
    std::snprintf(text, sizeof(text),
                  "the run would take %.3g vertex steps (steps x vertices over the cases), more "
                  "than %.3g (about ten minutes); a longer time_step, a shorter duration or fewer "
                  "segments, or %s to run it all the same",
                  estimate.vertex_steps, kMaxMotionVertexSteps, option.c_str());
    throw InputError(scene_path, 0, "dynamics", text);
  }
  if (estimate.output_bytes > kMaxMotionOutputBytes) {
    std::snprintf(text, sizeof(text),
                  "the run would write about %.3g bytes of CSV, more than %.3g; a larger "
                  "output_every, or %s to write it all the same",
                  estimate.output_bytes, kMaxMotionOutputBytes, option.c_str());
    throw InputError(scene_path, 0, "dynamics", text);
  }
}

}  // namespace rodfit
