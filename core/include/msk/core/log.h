#pragma once
/// Levelled logger and progress callbacks: libraries report here, the application decides what to print.
#include <functional>
#include <string>

namespace msk {

/// Log severity, from chatty to grave.
enum class LogLevel { Debug = 0, Info = 1, Warn = 2, Error = 3 };

/// Receives every message at or above the current level.
using LogSink = std::function<void(LogLevel, const std::string&)>;

/// Progress callback: fraction done in [0, 1] and a short stage label.
using ProgressFn = std::function<void(double fraction, const std::string& stage)>;

namespace log {
/// Installs the sink (nullptr: messages are dropped, the default). Returns the previous sink.
LogSink setSink(LogSink sink);
/// Sets the minimum level passed to the sink.
void setLevel(LogLevel level);
/// Current minimum level.
LogLevel level();
/// Sends a message to the sink if its level passes.
void write(LogLevel level, const std::string& message);
/// Debug message.
inline void debug(const std::string& m) { write(LogLevel::Debug, m); }
/// Informational message.
inline void info(const std::string& m) { write(LogLevel::Info, m); }
/// Warning.
inline void warn(const std::string& m) { write(LogLevel::Warn, m); }
/// Error message (errors that stop the work are thrown, not logged).
inline void error(const std::string& m) { write(LogLevel::Error, m); }
}  // namespace log
}  // namespace msk
