// rodfit.fit / simulate / rollout: bound to rodfit/pipeline/run.h once it is on main.
#include "bindings.h"

namespace rodfit_python {

void BindRun(py::module_&) {}

}  // namespace rodfit_python
