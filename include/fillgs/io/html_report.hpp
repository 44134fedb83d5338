#pragma once
// One self-contained HTML page from a fillgs Markdown report (`fillgs run`'s report.md,
// `fillgs bench`'s results.md): headings, paragraphs, lists, tables, code blocks and images,
// each image embedded as a data: URI so the page is one file that can be mailed or
// archived. It reads only the subset of Markdown fillgs writes.
#include <string>
#include <vector>

namespace fillgs {

struct HtmlReport {
  std::string html;
  std::vector<std::string> images;   ///< image paths the Markdown names, in order (relative to its folder)
  std::vector<std::string> missing;  ///< those that were not there (shown as a note in the page)
};

/// Converts `markdown`; images are read relative to `base_dir`.
HtmlReport markdown_to_html(const std::string& markdown, const std::string& base_dir, const std::string& title);

/// Writes `html_path` (atomically) from the Markdown file `md_path`; a missing image is one
/// warning line on stderr, not an error (the tables are still worth having).
HtmlReport write_html_report(const std::string& md_path, const std::string& html_path);

}  // namespace fillgs
