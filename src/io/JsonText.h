#pragma once
/// @file JsonText.h
/// @brief nlohmann::json::parse with a nesting limit: every JSON file and request we read goes
///        through parseJson().
#include <utility>

#include <nlohmann/json.hpp>

namespace splatwarp {

/// @brief Our files nest under 10 levels. 100,000 levels of "[[[" (200 KB) parse, but printing or
///        copying such a value recurses past the stack: a spec's "version": [[[...]]] crashed
///        eval and deform when the message printed it, a manifest entry crashed --merge.
constexpr int kMaxJsonDepth = 256;

/// @brief Thrown past kMaxJsonDepth. A json::exception, so each caller's handler names its file
///        as it does for a syntax error.
class JsonTooDeep : public nlohmann::json::exception {
public:
    JsonTooDeep() : exception(0, "[json.exception.too_deep] nested deeper than 256 levels") {}
};

/// @brief json::parse(input, follow) that throws JsonTooDeep past kMaxJsonDepth.
template <typename... Input>
nlohmann::json parseJsonFollowing(const nlohmann::json::parser_callback_t& follow, Input&&... input)
{
    return nlohmann::json::parse(std::forward<Input>(input)...,
                                 [&follow](int depth, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
                                     if (depth >= kMaxJsonDepth) throw JsonTooDeep(); // the outermost value is at depth 0
                                     return follow ? follow(depth, event, parsed) : true;
                                 });
}

/// @brief parseJson() without a callback of the caller's.
template <typename... Input>
nlohmann::json parseJson(Input&&... input)
{
    return parseJsonFollowing(nullptr, std::forward<Input>(input)...);
}

} // namespace splatwarp
