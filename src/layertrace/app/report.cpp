#include "layertrace/app/report.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "layertrace/app/commands.h"
#include "layertrace/util/error.h"

namespace lt {
namespace fs = std::filesystem;

namespace {

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((in.size() + 2) / 3 * 4);
  for (size_t i = 0; i < in.size(); i += 3) {
    uint32_t v = uint32_t(uint8_t(in[i])) << 16;
    if (i + 1 < in.size()) v |= uint32_t(uint8_t(in[i + 1])) << 8;
    if (i + 2 < in.size()) v |= uint32_t(uint8_t(in[i + 2]));
    out += t[(v >> 18) & 63];
    out += t[(v >> 12) & 63];
    out += i + 1 < in.size() ? t[(v >> 6) & 63] : '=';
    out += i + 2 < in.size() ? t[v & 63] : '=';
  }
  return out;
}

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::string escape(const std::string& s) {
  std::string o;
  for (char c : s) o += c == '<' ? "&lt;" : c == '>' ? "&gt;" : c == '&' ? "&amp;" : std::string(1, c);
  return o;
}

}  // namespace

void writeReport(const std::string& dir, const ReportPage& page) {
  ensureDirectory(dir, "--report");
  std::ostringstream html;
  html << "<!doctype html><html><head><meta charset=\"utf-8\"><title>" << escape(page.title)
       << "</title><style>body{font-family:sans-serif;margin:2em;background:#fafafa}figure{display:inline-block;margin:.5em;"
          "vertical-align:top}img{max-width:640px;border:1px solid #ccc}pre{background:#fff;padding:1em;border:1px solid #ddd;"
          "overflow:auto}.legend span{display:inline-block;padding:.2em .6em;margin-right:.4em;color:#fff}</style></head><body>\n"
       << "<h1>" << escape(page.title) << "</h1>\n";
  if (!page.table.empty()) html << "<h2>Table</h2><pre>" << escape(page.table) << "</pre>\n";
  html << "<p class=\"legend\">Classification images (class of each pixel's first ray): "
          "<span style=\"background:#1aa626\">correct hit</span><span style=\"background:#e61a1a\">wrong hit</span>"
          "<span style=\"background:#ccaa00\">false miss</span><span style=\"background:#2659f2\">information miss</span>"
          "<span style=\"background:#404040\">correct miss</span></p>\n<h2>Images</h2>\n";
  for (const auto& [caption, image] : page.images)
    html << "<figure><img src=\"data:image/png;base64," << base64(encodePng(*image)) << "\"><figcaption>" << escape(caption)
         << "</figcaption></figure>\n";
  for (const auto& [caption, file] : page.files)
    html << "<figure><img src=\"data:image/png;base64," << base64(slurp(file)) << "\"><figcaption>" << escape(caption)
         << "</figcaption></figure>\n";
  html << "<h2>Run data</h2><pre>" << escape(page.json.dump(2)) << "</pre></body></html>\n";
  writeFileAtomic((fs::path(dir) / "index.html").string(), html.str());
}

}  // namespace lt
