/// `splatwarp edit MODEL -o DIR [--port N] [--host H] [--token T] [--no-open]`: the browser editor.
/// Serves the page and the HTTP API (edit/EditServer.h, docs/editor-api.md) until Ctrl-C; saves go
/// to DIR/NAME/ and equal `deform --spec DIR/NAME/spec.json` with the same flags.
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <fcntl.h>
#include <filesystem>
#include <spawn.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>

#include "DeformArgs.h"
#include "core/Error.h"
#include "edit/EditRequest.h"
#include "edit/EditServer.h"

extern char** environ;

namespace splatwarp::cli {
namespace {

namespace fs = std::filesystem;

struct EditArgs {
    std::string host = "127.0.0.1";
    int port = 0;
    std::string token;
    bool noOpen = false;
};

/// The flags an edit run does not share with `deform`.
const char* const kEditOnlyFlags[] = {"-o", "--port", "--host", "--token", "--no-open"};

std::atomic<bool> gStop{false};

extern "C" void requestStop(int) { gStop = true; }

/// The page's files: next to the binary (build tree) or in PREFIX/share/splatwarp/web (installed).
std::string findWebDir()
{
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec) return "";
    for (const fs::path& dir : {exe.parent_path() / "web", exe.parent_path().parent_path() / "share" / "splatwarp" / "web"})
        if (fs::is_regular_file(dir / "index.html")) return dir.string();
    return "";
}

/// The deform flags given on this command line, to replay a save with `deform`.
std::string replayFlags(CLI::App* sub)
{
    std::string out;
    for (const CLI::Option* option : sub->get_options()) {
        if (option->get_positional() || option->count() == 0 || option == sub->get_help_ptr()) continue;
        bool editOnly = false;
        for (const char* flag : kEditOnlyFlags) editOnly = editOnly || option->check_name(flag);
        if (editOnly) continue;
        std::string name = option->get_name();
        out += (out.empty() ? "" : " ") + name;
        if (option->get_expected_min() == 0) continue; // a flag without a value
        for (const std::string& value : option->results()) out += " " + edit::shellQuoted(value);
    }
    return out;
}

bool isLoopback(const std::string& host)
{
    return host == "localhost" || host == "::1" || host == "[::1]" || host.rfind("127.", 0) == 0;
}

/// Open the page in the desktop's browser when there is a desktop; the URL is printed anyway.
void openBrowser(const std::string& url)
{
    if (!std::getenv("DISPLAY") && !std::getenv("WAYLAND_DISPLAY")) return;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
    const char* argv[] = {"xdg-open", url.c_str(), nullptr};
    pid_t pid = 0;
    if (posix_spawnp(&pid, "xdg-open", &actions, nullptr, const_cast<char* const*>(argv), environ) == 0)
        std::thread([pid] { waitpid(pid, nullptr, 0); }).detach();
    posix_spawn_file_actions_destroy(&actions);
}

void runEdit(const EditArgs& e, edit::EditServerOptions options)
{
    options.host = e.host;
    options.port = e.port;
    options.token = e.token;
    options.webDir = findWebDir();
    if (!isLoopback(e.host))
        std::fprintf(stderr, "splatwarp: warning: serving on %s: anyone who can reach this address and has the token can "
                             "pose, refine and save (no TLS)\n", e.host.c_str());
    edit::EditServer server(std::move(options));
    // Ctrl-C stops the server cleanly (a save under way finishes first) instead of the default cleanup.
    struct sigaction action {};
    action.sa_handler = requestStop;
    sigemptyset(&action.sa_mask);
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) sigaction(sig, &action, nullptr);
    server.start();
    std::printf("%s\n", server.url().c_str());
    std::fflush(stdout);
    if (!e.noOpen) openBrowser(server.url());
    while (!gStop) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    std::fprintf(stderr, "splatwarp: edit: stopping\n");
    server.stop();
}

const CommandRegistrar reg(32, [](CLI::App& app) {
    auto args = std::make_shared<DeformArgs>();
    auto e = std::make_shared<EditArgs>();
    DeformJobOptions& job = args->job;
    CLI::App* sub = app.add_subcommand("edit", "Pose a model in the browser: box-select handles, drag them with Stage I "
                                               "live, refine, save runs that `deform` replays (docs/editor-api.md)");
    sub->add_option("input", job.input, "Model to edit (any format deform reads)")->required();
    sub->add_option("-o,--output", job.outDir, "Folder the saves go into (created): Save writes DIR/NAME/ with spec.json, "
                                               "baseline.ply, deformed.ply, report.json")->required();
    sub->add_option("--port", e->port, "Port to listen on (0: a free one)")->check(inRange(0, 65535))->capture_default_str();
    sub->add_option("--host", e->host, "Address to listen on; anything but loopback is reachable from other machines")
        ->capture_default_str();
    sub->add_option("--token", e->token, "The token every request must carry (default: random per run)");
    sub->add_flag("--no-open", e->noOpen, "Do not open a browser (the URL is printed either way)");
    addDeformOptions(sub, *args);
    splitHelpLevels(sub, {"-o", "--port", "--host", "--token", "--no-open", "--stage1-only", "--iterations", "--cells"});
    sub->callback([args, e, sub] {
        edit::EditServerOptions options;
        options.replayFlags = replayFlags(sub); // as given: before the recipe fills in the other flags
        options.job = deformJobOptions(*args);
        if (options.job.render && options.job.stage1Only) throw UsageError("--render needs Stage II (drop --stage1-only)");
        if (!e->token.empty() && !edit::tokenWellFormed(e->token))
            throw UsageError("--token must be 16 to 128 of A-Z, a-z, 0-9, '_' and '-'");
        runEdit(*e, std::move(options));
    });
});

} // namespace
} // namespace splatwarp::cli
