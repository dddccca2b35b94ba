/// `splatwarp info FILE [--json] [--drop-invalid]`: summary of a Gaussian file.
#include <cstdio>
#include <nlohmann/json.hpp>

#include "Command.h"
#include "ReadArgs.h"
#include "core/Error.h"
#include "io/CloudStats.h"
#include "io/GaussianIO.h"

namespace splatwarp::cli {
namespace {

struct InfoArgs {
    std::string input;
    bool json = false;
    bool dropInvalid = false;
};

nlohmann::json toJson(const CloudStats& s, const ReadReport& r)
{
    const auto arr = [](const Vec3d& v) { return nlohmann::json::array({v.x, v.y, v.z}); };
    return {{"count", s.count},
            {"shDegree", s.shDegree},
            {"format", r.format},
            {"bboxMin", arr(s.bboxMin)},
            {"bboxMax", arr(s.bboxMax)},
            {"opacity", {{"min", s.opacityMin}, {"mean", s.opacityMean}, {"max", s.opacityMax}}},
            {"scale", {{"min", s.scaleMin}, {"median", s.scaleMedian}, {"max", s.scaleMax}}},
            {"quatNorm", {{"min", s.quatNormMin}, {"max", s.quatNormMax}}},
            {"invalidValues", s.invalidValues},
            {"dropped", r.dropped},
            {"notes", r.notes},
            {"unusableGaussians", r.invalidGaussians}};
}

const CommandRegistrar reg(20, [](CLI::App& app) {
    auto args = std::make_shared<InfoArgs>();
    CLI::App* sub = app.add_subcommand("info", "Print a summary of a Gaussian file " + kModelFormats);
    sub->add_option("file", args->input, "Input Gaussian file")->required();
    sub->add_flag("--json", args->json, "Print the summary as JSON on stdout");
    sub->add_flag("--drop-invalid", args->dropInvalid,
                  "Drop unusable Gaussians (NaN/Inf, overflowing scales, zero quaternions) before the statistics "
                  "(default: keep them, count them and warn)");
    sub->callback([args] {
        ReadOptions options;
        options.dropInvalid = args->dropInvalid;
        options.keepInvalid = !args->dropInvalid;
        ReadReport report;
        const GaussianCloud g = readGaussians(args->input, options, &report);
        const CloudStats s = computeCloudStats(g);
        const std::vector<CloudWarning> warnings = cloudWarnings(g, s);
        if (args->json) {
            nlohmann::json j = toJson(s, report);
            j["warnings"] = nlohmann::json::array();
            for (const CloudWarning& w : warnings)
                j["warnings"].push_back({{"kind", w.kind}, {"count", w.count}, {"message", w.message}});
            std::printf("%s\n", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace).c_str());
            return;
        }
        std::printf("file:            %s\n", args->input.c_str());
        std::printf("format:          %s\n", report.format.c_str());
        std::printf("count:           %zu\n", s.count);
        std::printf("sh degree:       %d\n", s.shDegree);
        std::printf("bbox min:        %g %g %g\n", s.bboxMin.x, s.bboxMin.y, s.bboxMin.z);
        std::printf("bbox max:        %g %g %g\n", s.bboxMax.x, s.bboxMax.y, s.bboxMax.z);
        std::printf("opacity:         min %g  mean %g  max %g\n", s.opacityMin, s.opacityMean, s.opacityMax);
        std::printf("scale:           min %g  median %g  max %g\n", s.scaleMin, s.scaleMedian, s.scaleMax);
        std::printf("quaternion norm: min %g  max %g\n", s.quatNormMin, s.quatNormMax);
        std::printf("invalid values:  %zu\n", s.invalidValues);
        if (report.dropped) std::printf("dropped:         %zu Gaussians\n", report.dropped);
        else if (report.invalidGaussians)
            std::printf("unusable:        %zu Gaussians (NaN/Inf, overflowing scales or centres, zero quaternions): "
                        "other commands refuse the file, --drop-invalid drops them\n",
                        report.invalidGaussians);
        for (const std::string& note : report.notes) std::printf("note:            %s\n", printable(note).c_str());
        for (const CloudWarning& w : warnings) std::printf("warning:         %s\n", w.message.c_str());
    });
});

} // namespace
} // namespace splatwarp::cli
