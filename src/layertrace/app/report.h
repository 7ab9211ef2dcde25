// A self-contained HTML page (no network: images inlined as data URIs) for people who would
// rather look than read: images, the table, and the run's JSON.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "layertrace/util/image.h"

namespace lt {

struct ReportPage {
  std::string title;
  std::string table;  ///< preformatted text table
  nlohmann::json json;
  std::vector<std::pair<std::string, const Image*>> images;  ///< caption, image (PNG-encoded inline)
  std::vector<std::pair<std::string, std::string>> files;    ///< caption, PNG file to inline (plots)
};

/// Writes DIR/index.html atomically.
void writeReport(const std::string& dir, const ReportPage& page);

}  // namespace lt
