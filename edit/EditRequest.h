#pragma once
/// @file EditRequest.h
/// @brief The editor server's request checks, as plain functions (tested on their own): the Host
///        header (DNS rebinding), the token, save names; and the random token of a run.
#include <string>

namespace splatwarp::edit {

/// @brief Whether a Host header names this server: localhost, 127.0.0.1, [::1] or the bound host,
///        with the bound port or none. Bound to a wildcard (0.0.0.0, ::) any IP literal is
///        accepted too: DNS rebinding needs a name, and the server's own address is not known.
bool hostAllowed(const std::string& hostHeader, const std::string& boundHost, int port);

/// @brief Whether `given` equals `token`, in time independent of where they differ.
bool tokenMatches(const std::string& given, const std::string& token);

/// @brief Whether a token given with --token is usable: 16 to 128 of [A-Za-z0-9_-] (it is put into
///        URLs and the page as it is).
bool tokenWellFormed(const std::string& token);

/// @brief 32 hex digits from /dev/urandom. @throws IoError when it cannot be read.
std::string randomToken();

/// @brief Empty when `name` is a usable save name (one path component: 1 to 100 of
///        [A-Za-z0-9._-], not starting with '.'), else the reason it is refused.
std::string saveNameProblem(const std::string& name);

/// @brief Whether a host is a wildcard bind address (0.0.0.0, ::).
bool isWildcardHost(const std::string& host);

/// @brief A word as a POSIX shell reads it back: as it is when made of [A-Za-z0-9._-/=:,+] only,
///        else in single quotes (a replay command's paths may hold spaces or ';').
std::string shellQuoted(const std::string& word);

/// @brief Whether a Range header asks for more than one range: refused (416), as cpp-httplib
///        would answer a few hundred "0-" with a copy of the body each.
bool tooManyRanges(const std::string& rangeHeader);

} // namespace splatwarp::edit
