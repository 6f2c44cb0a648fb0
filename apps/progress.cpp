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

ProgressFn stderrProgress(const std::string& task) {
  struct State {
    std::string stage;
    int lastPercent = -1;
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now(), last;
  };
  auto st = std::make_shared<State>();
  return [st, task](double f, const std::string& stage) {
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
/// The absolute target folder of `dir`, after checking that it can be written (see checkOutputFolder()).
fs::path checkedTarget(const std::string& dir) {
  fs::path target = fs::absolute(dir).lexically_normal();
  if (target.filename().empty()) target = target.parent_path();
  std::error_code ec;
  if (fs::exists(target, ec) && !fs::is_directory(target, ec)) throw IoError(dir, "exists and is not a folder");
  if (!fs::is_directory(target.parent_path(), ec)) throw IoError(dir, "parent folder does not exist");
  return target;
}
}  // namespace

void checkOutputFolder(const std::string& dir) { checkedTarget(dir); }

void writeFolderAtomically(const std::string& dir, const std::function<void(const std::string&)>& write) {
  const fs::path target = checkedTarget(dir);
  std::error_code ec;
  fs::path parent = target.parent_path();
  fs::path staging = parent / ("." + target.filename().string() + ".partial" + std::to_string(::getpid()));
  fs::remove_all(staging, ec);
  if (!fs::create_directory(staging, ec)) throw IoError(staging.string(), "cannot create folder: " + ec.message());
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
    throw;
  }
}

}  // namespace msk::cli
