#pragma once
/// @file Error.h
/// @brief Typed exceptions for user-facing failures. The CLI maps them to exit codes:
///        InputError/IoError -> 1 (bad input or failed job), UsageError -> 2.
#include <sstream>
#include <stdexcept>
#include <string>

namespace splatwarp {

/// @brief Base class of every splatwarp error; the message is meant for the user.
class Error : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// @brief The input (file, spec, parameter value) is malformed or inconsistent.
class InputError : public Error {
public:
    using Error::Error;
};

/// @brief A file could not be opened, read or written.
class IoError : public Error {
public:
    using Error::Error;
};

/// @brief The command line was wrong in a way only found after parsing (exit code 2).
class UsageError : public Error {
public:
    using Error::Error;
};

/// @brief Build a message from streamable parts: `throw InputError(msg(path, ": bad count ", n));`
template <typename... Args>
std::string msg(const Args&... args)
{
    std::ostringstream os;
    (os << ... << args);
    return os.str();
}

/// @brief Text safe to print on a terminal: control bytes and invalid UTF-8 become \\xNN, and
///        text beyond maxBytes is cut ("..."), so file contents echoed in a message cannot garble it.
std::string printable(const std::string& text, std::size_t maxBytes = 2000);

/// @brief printable() of a name shown inside one line of a message (a grid's name, a key): newlines
///        and tabs become \n and \t too.
std::string printableLine(const std::string& text);

} // namespace splatwarp
