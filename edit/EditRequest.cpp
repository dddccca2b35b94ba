#include "edit/EditRequest.h"

#include <cctype>
#include <fstream>

#include "core/Error.h"

namespace splatwarp::edit {

namespace {

/// "name:port" / "[v6]:port" / "name" into host and port text (empty when none).
void splitHost(const std::string& header, std::string& host, std::string& port)
{
    std::size_t colon = std::string::npos;
    if (!header.empty() && header.front() == '[') {
        const std::size_t close = header.find(']');
        if (close == std::string::npos) { host = header; port.clear(); return; }
        host = header.substr(0, close + 1);
        if (close + 1 < header.size() && header[close + 1] == ':') colon = close + 1;
    } else {
        colon = header.rfind(':');
        host = header.substr(0, colon);
    }
    port = colon == std::string::npos ? "" : header.substr(colon + 1);
}

bool isIpLiteral(const std::string& host)
{
    if (host.size() > 2 && host.front() == '[' && host.back() == ']') {
        for (char c : host.substr(1, host.size() - 2))
            if (!std::isxdigit(static_cast<unsigned char>(c)) && c != ':' && c != '.') return false;
        return true;
    }
    int dots = 0;
    for (char c : host) {
        if (c == '.') ++dots;
        else if (!std::isdigit(static_cast<unsigned char>(c))) return false;
    }
    return dots == 3;
}

std::string lower(std::string s)
{
    for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
    return s;
}

} // namespace

bool isWildcardHost(const std::string& host) { return host == "0.0.0.0" || host == "::" || host == "[::]"; }

bool hostAllowed(const std::string& hostHeader, const std::string& boundHost, int port)
{
    std::string host, portText;
    splitHost(lower(hostHeader), host, portText);
    if (!portText.empty() && portText != std::to_string(port)) return false;
    const std::string bound = lower(boundHost);
    if (host == "localhost" || host == "127.0.0.1" || host == "[::1]" || host == bound || "[" + bound + "]" == host)
        return true;
    return isWildcardHost(bound) && isIpLiteral(host);
}

bool tokenMatches(const std::string& given, const std::string& token)
{
    if (given.size() != token.size() || token.empty()) return false;
    unsigned char diff = 0;
    for (std::size_t i = 0; i < token.size(); ++i) diff |= static_cast<unsigned char>(given[i] ^ token[i]);
    return diff == 0;
}

bool tokenWellFormed(const std::string& token)
{
    if (token.size() < 16 || token.size() > 128) return false;
    for (char c : token)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-') return false;
    return true;
}

std::string randomToken()
{
    std::ifstream in("/dev/urandom", std::ios::binary);
    unsigned char bytes[16];
    if (!in.read(reinterpret_cast<char*>(bytes), sizeof bytes)) throw IoError("/dev/urandom: cannot read a token");
    static const char* hex = "0123456789abcdef";
    std::string token;
    for (unsigned char b : bytes) token += {hex[b >> 4], hex[b & 15]};
    return token;
}

std::string shellQuoted(const std::string& word)
{
    if (!word.empty() && word.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789._-/=:,+") == std::string::npos)
        return word;
    std::string out = "'";
    for (char c : word) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

bool tooManyRanges(const std::string& rangeHeader) { return rangeHeader.find(',') != std::string::npos; }

std::string saveNameProblem(const std::string& name)
{
    if (name.empty()) return "the save name is empty";
    if (name.size() > 100) return "the save name is longer than 100 characters";
    if (name.front() == '.') return "the save name must not start with '.'";
    for (char c : name)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '.' && c != '_' && c != '-')
            return "the save name must be one folder name of letters, digits, '.', '_' and '-'";
    return "";
}

} // namespace splatwarp::edit
