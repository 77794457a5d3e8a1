// The nesting bound every reader of a markup text checks before it parses (docs/formats.md,
// "Limits"): the experiment reader (io) and the camera file reader (vision). In model, the one
// layer both link, so that neither reader links the other's layer.
#pragma once

#include <string>

namespace rodfit {

/// The deepest nesting of a YAML, JSON or XML text (by its first character), as an upper bound
/// found without parsing: what a recursive-descent parser (OpenCV's FileStorage, yaml-cpp) would
/// recurse into. Camera files and experiment YAML are refused beyond a limit before they are
/// parsed (docs/formats.md, "Limits").
int MarkupNestingDepth(const std::string& text);

}  // namespace rodfit
