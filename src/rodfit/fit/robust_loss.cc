// The robust losses' names (fit.h, RobustLossName), apart from the fit itself: the experiment
// reader (io/experiment.cc) parses `fit.loss` with them, and an object of their own keeps that
// reader, and so `rodfit simulate`, from linking Ceres (docs/cli.md, "Start-up").
#include "rodfit/fit/fit.h"

namespace rodfit {

const char* RobustLossName(RobustLoss loss) {
  switch (loss) {
    case RobustLoss::kNone: return "none";
    case RobustLoss::kHuber: return "huber";
    case RobustLoss::kCauchy: return "cauchy";
    case RobustLoss::kSoftL1: return "soft_l1";
  }
  return "none";
}

}  // namespace rodfit
