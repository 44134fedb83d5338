#include "fillgs/io/html_report.hpp"

#include <filesystem>
#include <iostream>
#include <sstream>

#include "fillgs/base/error.hpp"
#include "fillgs/base/fs_util.hpp"

namespace fillgs {

namespace {

std::string escape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

/// Inline Markdown: `code` and **bold**; everything else escaped.
std::string inline_html(const std::string& s) {
  std::string out;
  bool code = false, bold = false;
  std::string run;
  auto flush = [&] { out += escape(run), run.clear(); };
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '`') {
      flush();
      out += code ? "</code>" : "<code>";
      code = !code;
    } else if (!code && s.compare(i, 2, "**") == 0) {
      flush();
      out += bold ? "</b>" : "<b>";
      bold = !bold;
      ++i;
    } else {
      run += s[i];
    }
  }
  flush();
  if (code) out += "</code>";
  if (bold) out += "</b>";
  return out;
}

std::string base64(const std::string& bytes) {
  static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const unsigned v = (unsigned(uint8_t(bytes[i])) << 16) | (unsigned(uint8_t(bytes[i + 1])) << 8) | unsigned(uint8_t(bytes[i + 2]));
    out += table[(v >> 18) & 63], out += table[(v >> 12) & 63], out += table[(v >> 6) & 63], out += table[v & 63];
  }
  if (i < bytes.size()) {
    const bool two = i + 1 < bytes.size();
    const unsigned v = (unsigned(uint8_t(bytes[i])) << 16) | (two ? unsigned(uint8_t(bytes[i + 1])) << 8 : 0u);
    out += table[(v >> 18) & 63], out += table[(v >> 12) & 63];
    out += two ? table[(v >> 6) & 63] : '=';
    out += '=';
  }
  return out;
}

std::string mime_of(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".jpg" || ext == ".jpeg") return "image/jpeg";
  if (ext == ".svg") return "image/svg+xml";
  return "image/png";
}

std::vector<std::string> table_cells(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  for (size_t i = 1; i < line.size(); ++i) {  // past the leading '|'
    if (line[i] == '|') {
      size_t a = cell.find_first_not_of(' '), b = cell.find_last_not_of(' ');
      cells.push_back(a == std::string::npos ? std::string() : cell.substr(a, b - a + 1));
      cell.clear();
    } else {
      cell += line[i];
    }
  }
  return cells;
}

bool is_separator_row(const std::string& line) { return line.find_first_not_of("|-: ") == std::string::npos; }

}  // namespace

HtmlReport markdown_to_html(const std::string& markdown, const std::string& base_dir, const std::string& title) {
  HtmlReport report;
  std::ostringstream body;
  std::vector<std::string> lines;
  {
    std::istringstream in(markdown);
    for (std::string line; std::getline(in, line);) lines.push_back(line);
  }
  std::string paragraph;
  auto end_paragraph = [&] {
    if (!paragraph.empty()) body << "<p>" << inline_html(paragraph) << "</p>\n";
    paragraph.clear();
  };
  for (size_t i = 0; i < lines.size(); ++i) {
    const std::string& line = lines[i];
    if (line.rfind("```", 0) == 0) {  // a code block, verbatim
      end_paragraph();
      body << "<pre><code>";
      for (++i; i < lines.size() && lines[i].rfind("```", 0) != 0; ++i) body << escape(lines[i]) << "\n";
      body << "</code></pre>\n";
    } else if (line.rfind('#', 0) == 0) {
      end_paragraph();
      const size_t level = std::min<size_t>(line.find_first_not_of('#'), 6);
      body << "<h" << level << ">" << inline_html(line.substr(std::min(line.size(), level + 1))) << "</h" << level << ">\n";
    } else if (line.rfind("![", 0) == 0 && line.find("](") != std::string::npos && line.back() == ')') {
      end_paragraph();
      const size_t mid = line.find("](");
      const std::string alt = line.substr(2, mid - 2), file = line.substr(mid + 2, line.size() - mid - 3);
      report.images.push_back(file);
      const std::string path = join_path(base_dir, file);
      std::error_code ec;
      if (std::filesystem::is_regular_file(path, ec)) {
        body << "<figure><img alt=\"" << escape(alt) << "\" src=\"data:" << mime_of(file) << ";base64," << base64(read_file(path))
             << "\"><figcaption>" << escape(alt) << "</figcaption></figure>\n";
      } else {
        report.missing.push_back(file);
        body << "<p class=\"missing\">missing image " << escape(file) << "</p>\n";
      }
    } else if (line.rfind('|', 0) == 0) {
      end_paragraph();
      body << "<table>\n";
      bool header = i + 1 < lines.size() && is_separator_row(lines[i + 1]);
      for (; i < lines.size() && lines[i].rfind('|', 0) == 0; ++i) {
        if (is_separator_row(lines[i])) continue;
        const char* tag = header ? "th" : "td";
        body << "<tr>";
        for (const std::string& c : table_cells(lines[i])) body << "<" << tag << ">" << inline_html(c) << "</" << tag << ">";
        body << "</tr>\n";
        header = false;
      }
      --i;
      body << "</table>\n";
    } else if (line.rfind("- ", 0) == 0) {
      end_paragraph();
      body << "<ul>\n";
      for (; i < lines.size() && lines[i].rfind("- ", 0) == 0; ++i) body << "<li>" << inline_html(lines[i].substr(2)) << "</li>\n";
      --i;
      body << "</ul>\n";
    } else if (line.find_first_not_of(' ') == std::string::npos) {
      end_paragraph();
    } else {
      paragraph += (paragraph.empty() ? "" : " ") + line;
    }
  }
  end_paragraph();
  std::ostringstream html;
  html << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" << escape(title) << "</title>\n<style>\n"
       << "body { font-family: 'DejaVu Sans', Helvetica, Arial, sans-serif; max-width: 1500px; margin: 2em auto; padding: 0 1em; color: #222; }\n"
       << "table { border-collapse: collapse; margin: 1em 0; font-size: 0.8em; display: block; overflow-x: auto; }\n"
       << "th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }\n"
       << "th { background: #f0f0f0; } td, th { white-space: nowrap; }\n"
       << "td:first-child, td:nth-child(2), th:first-child, th:nth-child(2) { text-align: left; }\n"
       << "tr:nth-child(even) td { background: #fafafa; }\n"
       << "figure { margin: 1em 0; } img { max-width: 100%; border: 1px solid #ddd; } figcaption { color: #666; font-size: 0.85em; }\n"
       << "pre { background: #f6f6f6; padding: 0.8em; overflow-x: auto; } code { font-family: 'DejaVu Sans Mono', monospace; }\n"
       << ".missing { color: #b00; }\n</style>\n</head>\n<body>\n"
       << body.str() << "</body>\n</html>\n";
  report.html = html.str();
  return report;
}

HtmlReport write_html_report(const std::string& md_path, const std::string& html_path) {
  const std::string dir = std::filesystem::path(md_path).parent_path().string();
  const std::string markdown = read_file(md_path);
  // The page's title: the report's first heading.
  std::string title = std::filesystem::path(md_path).stem().string();
  if (markdown.rfind("# ", 0) == 0) title = markdown.substr(2, markdown.find('\n') - 2);
  HtmlReport r = markdown_to_html(markdown, dir.empty() ? "." : dir, title);
  write_file_atomically(html_path, r.html);
  for (const std::string& m : r.missing) std::cerr << "warning: " << html_path << ": image " << m << " is missing\n";
  return r;
}

}  // namespace fillgs
