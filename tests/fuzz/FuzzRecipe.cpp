/// libFuzzer target: parseRecipe() (deform --recipe FILE.json), then recipeFlags() and recipeJson()
/// of what it accepts.
#include <cstddef>
#include <cstdint>
#include <string>

#include "job/Recipe.h"
#include "core/Error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
    try {
        const splatwarp::Recipe r = splatwarp::parseRecipe(std::string(reinterpret_cast<const char*>(data), size), "fuzz-input");
        (void)splatwarp::recipeFlags(r);
        (void)splatwarp::recipeJson(r).dump();
    } catch (const splatwarp::Error&) {
    }
    return 0;
}
