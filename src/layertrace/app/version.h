// What `layertrace --version` and `layertrace tracers` print.
#pragma once

#include <string>

namespace lt {

/// "layertrace 0.2.0 (commit …)" and one line per enabled feature and library version.
std::string versionText(bool viewer);

/// Every tracer of the registry with its kind, paper and parameters (flag, default, help, older
/// spelling), then every effect with its options.
std::string tracersText();

}  // namespace lt
