// OUT/report.html, the cohort's QC page: one self-contained HTML file (styles, script and thumbnails inside it).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "cohort.h"
#include "commands.h"
#include "msk/core/atomic_file.h"
#include "msk/core/error.h"
#include "msk/core/log.h"
#include "msk/imaging/checksum.h"
#include "msk/segmentation/png_file.h"

namespace fs = std::filesystem;

namespace msk::cli {

namespace {

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// A case whose results were read (this run's or an earlier one's).
bool finished(const Case& c) { return c.status == "ok" || c.status == "done" || c.status == "stale"; }

/// How far each finished case's volume of each object lies from the cohort's median, in robust standard deviations
/// (1.4826 median absolute deviations, at least 1 % of the median: closer volumes are alike); only with at least 4
/// finished cases.
std::map<std::string, std::map<std::string, double>> volumeDeviations(const std::vector<Case>& cases) {
  std::map<std::string, std::vector<double>> byObject;
  for (const Case& c : cases)
    if (finished(c))
      for (const auto& [name, v] : c.volumesMl) byObject[name].push_back(v);
  std::map<std::string, std::map<std::string, double>> out;  // object -> case -> deviation
  for (const auto& [name, values] : byObject) {
    if (values.size() < 4) continue;
    const double m = median(values);
    std::vector<double> spread;
    for (double v : values) spread.push_back(std::abs(v - m));
    const double sigma = std::max(1.4826 * median(spread), 0.01 * std::abs(m));
    if (!(sigma > 0)) continue;
    for (const Case& c : cases)
      if (finished(c))
        for (const auto& [object, v] : c.volumesMl)
          if (object == name) out[name][c.name] = (v - m) / sigma;
  }
  return out;
}

/// A table cell holding a number (sorted as one); empty if `v` is not finite.
std::string numberCell(double v, int digits, const std::string& cls = "", const std::string& title = "") {
  if (!std::isfinite(v)) return "<td data-v=\"\"></td>";
  return "<td data-v=\"" + fixed(v, 6) + "\"" + (cls.empty() ? "" : " class=\"" + cls + "\"") +
         (title.empty() ? "" : " title=\"" + markupEscaped(title) + "\"") + ">" + fixed(v, digits) + "</td>";
}

constexpr const char* kStyle = R"(
body { font: 14px/1.4 system-ui, sans-serif; margin: 1.5em; color: #1b1b1b; background: #fafafa; }
h1 { font-size: 1.4em; margin: 0 0 .3em; }
.summary { margin: 0 0 1em; color: #444; }
.controls { margin: 0 0 .8em; }
table { border-collapse: collapse; background: #fff; }
th, td { border: 1px solid #ccc; padding: .25em .5em; text-align: right; vertical-align: middle; }
th { background: #eee; cursor: pointer; user-select: none; position: sticky; top: 0; }
th[aria-sort=ascending]::after { content: " \25B2"; }
th[aria-sort=descending]::after { content: " \25BC"; }
td.text, th.text { text-align: left; }
td.message { max-width: 32em; text-align: left; font-size: 12px; color: #555; }
tr.failed td.status, tr.interrupted td.status { background: #f6c6c6; }
tr.not-run td.status, tr.not-started td.status, tr.skipped td.status, tr.elsewhere td.status { background: #eee; }
td.quality-doubtful { background: #fbe7b0; }
td.quality-failed { background: #f6c6c6; }
td.outlier { background: #fbe7b0; font-weight: bold; }
img.thumb { width: 240px; height: 110px; object-fit: cover; object-position: top; display: block; }
)";

constexpr const char* kScript = R"(
(function () {
  var table = document.getElementById('cases');
  var body = table.tBodies[0];
  var heads = Array.prototype.slice.call(table.tHead.rows[0].cells);
  function value(row, i) {
    var cell = row.cells[i];
    return cell.hasAttribute('data-v') ? cell.getAttribute('data-v') : cell.textContent;
  }
  function sortBy(i, dir) {
    var numeric = heads[i].getAttribute('data-type') === 'number';
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (a, b) {
      var x = value(a, i), y = value(b, i);
      if (numeric) {
        if (x === '' && y === '') return 0;
        if (x === '') return 1;
        if (y === '') return -1;
        return dir * (parseFloat(x) - parseFloat(y));
      }
      return dir * x.localeCompare(y, undefined, {numeric: true});
    });
    rows.forEach(function (r) { body.appendChild(r); });
    heads.forEach(function (h) { h.removeAttribute('aria-sort'); });
    heads[i].setAttribute('aria-sort', dir > 0 ? 'ascending' : 'descending');
  }
  function filter(status) {
    Array.prototype.forEach.call(body.rows, function (r) {
      r.hidden = status !== '' && r.getAttribute('data-status') !== status;
    });
    document.getElementById('status').value = status;
  }
  heads.forEach(function (h, i) {
    h.addEventListener('click', function () {
      sortBy(i, h.getAttribute('aria-sort') === 'ascending' ? -1 : 1);
    });
  });
  document.getElementById('status').addEventListener('change', function (e) { filter(e.target.value); });
  // report.html#sort=<column>&dir=asc|desc&status=<status>
  var asked = {};
  location.hash.replace(/^#/, '').split('&').forEach(function (kv) {
    var p = kv.split('=');
    if (p.length === 2) asked[decodeURIComponent(p[0])] = decodeURIComponent(p[1]);
  });
  if (asked.sort) {
    var i = heads.findIndex(function (h) { return h.getAttribute('data-key') === asked.sort; });
    if (i >= 0) sortBy(i, asked.dir === 'desc' ? -1 : 1);
  }
  if (asked.status) filter(asked.status);
})();
)";

}  // namespace

void writeCohortPage(const std::string& out, const std::vector<Case>& cases, const std::string& title) {
  // The objects, in the order the cases list them; whether anything was scored.
  std::vector<std::string> objects;
  bool scored = false;
  std::map<std::string, long> statusCount;
  for (const Case& c : cases) {
    ++statusCount[c.status];
    scored = scored || !c.scores.empty();
    for (const auto& [name, v] : c.volumesMl)
      if (std::find(objects.begin(), objects.end(), name) == objects.end()) objects.push_back(name);
  }
  const auto deviations = volumeDeviations(cases);
  const fs::path root = fs::absolute(out).lexically_normal();

  std::ostringstream h;
  h << "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
    << "<meta name=\"viewport\" content=\"width=device-width\"><title>mskseg cohort: " << markupEscaped(title)
    << "</title><style>" << kStyle << "</style></head><body>\n";
  h << "<h1>mskseg cohort report</h1>\n<p class=\"summary\">" << markupEscaped(title) << ": " << cases.size()
    << " case(s)";
  for (const auto& [status, n] : statusCount) h << ", " << n << " " << markupEscaped(status);
  h << ". Volumes more than 3.5 robust standard deviations from the cohort's median are marked. Mskseg "
    << markupEscaped(MSK_VERSION) << ".</p>\n";
  h << "<div class=\"controls\"><label>Status <select id=\"status\"><option value=\"\">all</option>";
  for (const auto& [status, n] : statusCount)
    h << "<option value=\"" << markupEscaped(status) << "\">" << markupEscaped(status) << " (" << n << ")</option>";
  h << "</select></label> Click a column's title to sort by it.</div>\n";

  h << "<table id=\"cases\"><thead><tr>"
    << "<th class=\"text\" data-key=\"case\" data-type=\"text\">case</th>"
    << "<th class=\"text\" data-key=\"status\" data-type=\"text\">status</th>"
    << "<th class=\"text\" data-key=\"quality\" data-type=\"text\">quality</th>"
    << "<th data-key=\"seconds\" data-type=\"number\">seconds</th>";
  for (const std::string& o : objects)
    h << "<th data-key=\"volume:" << markupEscaped(o) << "\" data-type=\"number\">" << markupEscaped(o) << " mL</th>";
  if (scored)
    h << "<th data-key=\"mean_dice\" data-type=\"number\">mean Dice</th>"
      << "<th data-key=\"min_dice\" data-type=\"number\">min Dice</th>"
      << "<th data-key=\"mean_assd\" data-type=\"number\">mean ASSD mm</th>";
  h << "<th class=\"text\" data-key=\"qc\" data-type=\"text\">QC</th>"
    << "<th class=\"text\" data-key=\"message\" data-type=\"text\">message</th></tr></thead>\n<tbody>\n";

  for (const Case& c : cases) {
    h << "<tr class=\"" << markupEscaped(c.status) << "\" data-status=\"" << markupEscaped(c.status) << "\">"
      << "<td class=\"text\">" << markupEscaped(c.name) << "</td><td class=\"text status\">" << markupEscaped(c.status)
      << "</td><td class=\"text quality-" << markupEscaped(c.quality) << "\">" << markupEscaped(c.quality) << "</td>"
      << numberCell(c.seconds > 0 ? c.seconds : std::nan(""), 1);
    for (const std::string& o : objects) {
      double v = std::nan("");
      for (const auto& [name, ml] : c.volumesMl)
        if (name == o) v = ml;
      std::string cls, why;
      if (const auto obj = deviations.find(o); obj != deviations.end())
        if (const auto d = obj->second.find(c.name); d != obj->second.end() && std::abs(d->second) > 3.5) {
          cls = "outlier";
          why = fixed(d->second, 1) + " robust SD from the cohort's median";
        }
      h << numberCell(v, 1, cls, why);
    }
    if (scored) {
      double assd = 0;
      for (const ObjectScore& s : c.scores) assd += s.assdMm;
      h << numberCell(c.meanDice, 3) << numberCell(c.minDice, 3)
        << numberCell(c.scores.empty() ? std::nan("") : assd / static_cast<double>(c.scores.size()), 2);
    }
    h << "<td class=\"text\">";
    std::error_code ec;
    if (finished(c) && fs::is_regular_file(c.mosaicPath, ec)) {
      try {
        const std::string thumb = base64(thumbnailJpeg(c.mosaicPath, 240));
        const std::string link = fs::path(c.mosaicPath).lexically_relative(root).generic_string();
        h << "<a href=\"" << markupEscaped(link) << "\"><img class=\"thumb\" alt=\"QC of " << markupEscaped(c.name)
          << "\" src=\"data:image/jpeg;base64," << thumb << "\"></a>";
      } catch (const Error& e) {
        log::warn(std::string("QC thumbnail of ") + c.name + " left out: " + e.what());
      }
    }
    h << "</td><td class=\"message\">" << markupEscaped(c.message) << "</td></tr>\n";
  }
  char when[32];
  const std::time_t now = std::time(nullptr);
  std::strftime(when, sizeof when, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  h << "</tbody></table>\n<p class=\"summary\">Written " << when << ".</p>\n<script>" << kScript
    << "</script>\n</body></html>\n";

  const std::string path = (root / "report.html").string();
  const std::string text = h.str();
  writeAtomically(path, [&](const std::string& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    if (!f.flush()) throw IoError(path, "cannot write");
  });
}

}  // namespace msk::cli
