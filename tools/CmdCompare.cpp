/// `splatwarp compare A B [--json]`: PSNR and SSIM of two images.
#include <cmath>
#include <cstdio>
#include <limits>
#include <nlohmann/json.hpp>

#include "Command.h"
#include "core/Error.h"
#include "image/ImageIO.h"
#include "image/Metrics.h"

namespace splatwarp::cli {
namespace {

struct CompareArgs {
    std::string a, b;
    bool json = false;
};


const CommandRegistrar reg(61, [](CLI::App& app) {
    auto args = std::make_shared<CompareArgs>();
    CLI::App* sub = app.add_subcommand(
        "compare", "PSNR (dB) and SSIM (11x11 Gaussian window, sigma 1.5) of two images of the same size, colour channels only, on display values (an EXR is sRGB-encoded first)");
    sub->add_option("a", args->a, "First image (.png or .exr)")->required()->check(CLI::ExistingFile);
    sub->add_option("b", args->b, "Second image (.png or .exr)")->required()->check(CLI::ExistingFile);
    sub->add_flag("--json", args->json, "Print {\"psnr\": ..., \"ssim\": ...} on stdout (psnr null for identical images)");
    sub->callback([args] {
        const Image a = readImage(args->a), b = readImage(args->b);
        double p = 0, s = 0;
        try {
            p = psnr(a, b);
            s = ssim(a, b);
        } catch (const InputError& e) {
            throw InputError(msg(args->a, " vs ", args->b, ": ", e.what()));
        }
        const bool identical = p == std::numeric_limits<double>::infinity(); // psnr()'s mse of 0
        if (args->json) {
            nlohmann::json j{{"psnr", identical ? nlohmann::json(nullptr) : nlohmann::json(p)}, {"ssim", s}};
            std::printf("%s\n", j.dump(2).c_str());
        } else {
            std::printf("PSNR %s dB  SSIM %.6f\n", identical ? "inf" : msg(p).c_str(), s);
        }
    });
});

} // namespace
} // namespace splatwarp::cli
