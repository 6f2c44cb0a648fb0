#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <memory>

#include "commands.h"
#include "msk/core/error.h"

namespace fs = std::filesystem;

namespace msk::cli {

Json commandLineJson(const std::string& command, const std::vector<std::string>& args) {
  Json cmd = Json::array();
  cmd.push_back("mskseg");
  cmd.push_back(command);
  for (const auto& a : args) cmd.push_back(a);
  return cmd;
}

std::string markupEscaped(const std::string& s) {
  std::string out;
  for (char ch : s) {
    switch (ch) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += ch;
    }
  }
  return out;
}

namespace {
bool progressTags = false;

/// Slicer's progress protocol: a <filter-start> block naming the task, <filter-progress> with the fraction done,
/// <filter-end> when the task reports its stage "done" (until then the fraction stops short of 1).
void printProgressTags(const std::string& task, double f, bool first, const std::string& stage) {
  if (first)
    std::cout << "<filter-start>\n<filter-name>mskseg " << task << "</filter-name>\n<filter-comment>" << stage
              << "</filter-comment>\n</filter-start>\n";
  const bool done = stage == "done";
  std::cout << "<filter-progress>" << (done ? 1.0 : std::min(f, 0.99)) << "</filter-progress>\n";
  if (done) std::cout << "<filter-end>\n<filter-name>mskseg " << task << "</filter-name>\n</filter-end>\n";
  std::cout.flush();
}
}  // namespace

void setProgressTags(bool on) { progressTags = on; }

ProgressFn stderrProgress(const std::string& task) {
  struct State {
    std::string stage;
    int lastPercent = -1, lastTagPercent = -1;
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now(), last;
  };
  auto st = std::make_shared<State>();
  return [st, task](double f, const std::string& stage) {
    if (progressTags) {
      const int pct = stage == "done" ? 100 : static_cast<int>(std::floor(100.0 * std::min(0.99, std::max(0.0, f))));
      if (pct != st->lastTagPercent) printProgressTags(task, pct / 100.0, st->lastTagPercent < 0, stage);
      st->lastTagPercent = pct;
    }
    if (log::level() > LogLevel::Info) return;
    int pct = static_cast<int>(std::lround(100.0 * std::min(1.0, std::max(0.0, f))));
    auto now = std::chrono::steady_clock::now();
    bool newStage = stage != st->stage;
    if (!newStage && pct == st->lastPercent) return;
    if (!newStage && pct != 100 && (pct - st->lastPercent < 10 || now - st->last < std::chrono::milliseconds(500)))
      return;
    st->stage = stage;
    st->lastPercent = pct;
    st->last = now;
    double sec = std::chrono::duration<double>(now - st->start).count();
    std::cerr << "mskseg " << task << ": " << stage << " " << pct << "% (" << std::fixed;
    std::cerr.precision(1);
    std::cerr << sec << " s)" << std::endl;
    std::cerr.unsetf(std::ios::floatfield);
  };
}

namespace {
/// The folders above `target` that do not exist yet, outermost first. Throws IoError naming `shown` if the nearest
/// existing one is not a folder.
std::vector<fs::path> missingParents(const fs::path& target, const std::string& shown) {
  std::vector<fs::path> missing;
  std::error_code ec;
  fs::path p = target.parent_path();
  while (!p.empty() && !fs::exists(p, ec)) {
    missing.insert(missing.begin(), p);
    if (p == p.parent_path()) break;
    p = p.parent_path();
  }
  if (!p.empty() && !fs::is_directory(p, ec)) throw IoError(shown, p.string() + " is not a folder");
  return missing;
}

/// The absolute target folder of `dir`, after checking that it can be written (see checkOutputFolder()).
fs::path checkedTarget(const std::string& dir) {
  fs::path target = fs::absolute(dir).lexically_normal();
  if (target.filename().empty()) target = target.parent_path();
  std::error_code ec;
  if (fs::exists(target, ec) && !fs::is_directory(target, ec)) throw IoError(dir, "exists and is not a folder");
  missingParents(target, dir);
  return target;
}

/// Creates the missing folders above `target`; returns those it created, outermost first.
std::vector<fs::path> createParents(const fs::path& target, const std::string& shown) {
  const std::vector<fs::path> missing = missingParents(target, shown);
  std::error_code ec;
  for (const fs::path& p : missing)
    if (!fs::create_directory(p, ec) && !fs::is_directory(p))
      throw IoError(shown, "cannot create folder " + p.string() + ": " + ec.message());
  return missing;
}

/// Removes the folders createParents() made, innermost first, where they are still empty.
void removeCreated(const std::vector<fs::path>& created) {
  std::error_code ec;
  for (auto p = created.rbegin(); p != created.rend(); ++p)
    if (fs::is_empty(*p, ec)) fs::remove(*p, ec);
}
}  // namespace

void checkOutputFolder(const std::string& dir) { checkedTarget(dir); }

void checkOutputFile(const std::string& path) {
  const fs::path target = fs::absolute(path).lexically_normal();
  std::error_code ec;
  if (target.filename().empty() || fs::is_directory(target, ec)) throw IoError(path, "is a folder, not a file name");
  missingParents(target, path);
}

void writeFileWithParents(const std::string& path, const std::function<void()>& write) {
  const std::vector<fs::path> created = createParents(fs::absolute(path).lexically_normal(), path);
  try {
    write();
  } catch (...) {
    removeCreated(created);
    throw;
  }
}

void writeFolderAtomically(const std::string& dir, const std::function<void(const std::string&)>& write) {
  const fs::path target = checkedTarget(dir);
  const std::vector<fs::path> created = createParents(target, dir);
  std::error_code ec;
  fs::path parent = target.parent_path();
  fs::path staging = parent / ("." + target.filename().string() + ".partial" + std::to_string(::getpid()));
  fs::remove_all(staging, ec);
  if (!fs::create_directory(staging, ec)) {
    removeCreated(created);
    throw IoError(staging.string(), "cannot create folder: " + ec.message());
  }
  try {
    write(staging.string());
    if (!fs::exists(target, ec)) {
      fs::rename(staging, target, ec);
      if (ec) throw IoError(dir, "cannot move results into place: " + ec.message());
      return;
    }
    for (const auto& e : fs::recursive_directory_iterator(staging)) {
      fs::path rel = fs::relative(e.path(), staging);
      if (e.is_directory()) {
        fs::create_directories(target / rel, ec);
      } else {
        fs::create_directories((target / rel).parent_path(), ec);
        fs::rename(e.path(), target / rel, ec);
        if (ec) throw IoError((target / rel).string(), "cannot move result into place: " + ec.message());
      }
    }
    fs::remove_all(staging, ec);
  } catch (...) {
    fs::remove_all(staging, ec);
    removeCreated(created);
    throw;
  }
}

}  // namespace msk::cli
