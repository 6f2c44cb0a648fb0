#include "msk/core/log.h"

#include <mutex>

namespace msk::log {
namespace {
std::mutex& sinkMutex() {
  static std::mutex m;
  return m;
}
LogSink& currentSink() {
  static LogSink s;
  return s;
}
LogLevel& currentLevel() {
  static LogLevel l = LogLevel::Info;
  return l;
}
}  // namespace

LogSink setSink(LogSink sink) {
  std::lock_guard<std::mutex> lock(sinkMutex());
  LogSink old = std::move(currentSink());
  currentSink() = std::move(sink);
  return old;
}

void setLevel(LogLevel level) { currentLevel() = level; }

LogLevel level() { return currentLevel(); }

void write(LogLevel lvl, const std::string& message) {
  if (lvl < currentLevel()) return;
  std::lock_guard<std::mutex> lock(sinkMutex());
  if (currentSink()) currentSink()(lvl, message);
}
}  // namespace msk::log
