/// libFuzzer target: the manifest as resume and merge read it (parseManifest(), then every field
/// they take from a manifest that passed), and mergeFailures() over it.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "job/Sequence.h"
#include "core/Error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    using json = nlohmann::json;
    try {
        const json m = splatwarp::parseManifest(std::string(reinterpret_cast<const char*>(data), size), "fuzz-input");
        const std::string item = m["itemName"];
        for (const json& e : m["entries"]) {
            (void)e[item].get<int>();
            if (e["status"] != "done") continue;
            for (const json& f : e["files"])
                (void)(f["path"].get<std::string>().size() + f["bytes"].get<std::uintmax_t>() + f["fnv1a64"].get<std::string>().size());
        }
        json merged = m;
        merged["entries"] = m["entries"];
        (void)splatwarp::mergeFailures(merged);
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
