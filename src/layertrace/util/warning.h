// Warnings: something was wrong with an input and the library carried on (a texture that is
// missing or does not decode leaves its material untextured). One line each, on stderr.
#pragma once

#include <functional>
#include <string>

namespace lt {

/// Prints "layertrace: warning: <message>" as one line on stderr (safe from any thread), or
/// hands the message to the sink setWarningSink installed.
void warning(const std::string& message);

using WarningSink = std::function<void(const std::string&)>;
/// Installs `sink` (empty: stderr again) and returns the previous one. Tests collect warnings so.
WarningSink setWarningSink(WarningSink sink);

}  // namespace lt
