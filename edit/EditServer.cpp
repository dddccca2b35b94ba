#include "edit/EditServer.h"

#include <httplib.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>

#include "core/AtomicFile.h"
#include "core/Error.h"
#include "core/Progress.h"
#include "core/RunControl.h"
#include "edit/EditRequest.h"
#include "edit/GaussianLayout.h"
#include "deform/AnimSpec.h"
#include "job/DeformSession.h"
#include "io/JsonText.h"

namespace splatwarp::edit {

namespace fs = std::filesystem;

namespace {

/// An answer with a status: thrown by a handler, turned into the response by guarded().
struct HttpError {
    int status;
    std::string message;
};

const char* kJson = "application/json";
const char* kBinary = "application/octet-stream";

void sendJson(httplib::Response& res, const nlohmann::json& body, int status = 200)
{
    res.status = status;
    // Replaced, not thrown on: a message may quote bytes of a request that are not UTF-8.
    res.set_content(body.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n", kJson);
}

void sendError(httplib::Response& res, int status, const std::string& message)
{
    sendJson(res, {{"error", message}}, status);
}

/// The token of a request: `?token=` or `Authorization: Bearer T`.
std::string requestToken(const httplib::Request& req)
{
    if (req.has_param("token")) return req.get_param_value("token");
    const std::string auth = req.get_header_value("Authorization");
    const std::string bearer = "Bearer ";
    return auth.compare(0, bearer.size(), bearer) == 0 ? auth.substr(bearer.size()) : std::string();
}

/// The default spec: its graph block is the session's (the flags --nodes/--k/--seed apply).
DeformSpec graphSpec() { return DeformSpec{}; }

nlohmann::json graphBlock(const GraphOptions& graph) { return {{"nodes", graph.nodes}, {"k", graph.k}, {"seed", graph.seed}}; }

/// ?frame=F: a whole number, else 400.
int frameParam(const std::string& text)
{
    char* end = nullptr;
    const long f = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0' || f < 0 || f > 1000000) throw HttpError{400, msg("frame: not a frame number: '", printable(text, 40), "'")};
    return int(f);
}

/// A web file served at a fixed URL: the server never opens a path a client names.
struct WebFile {
    std::string body;
    std::string type;
};

} // namespace

struct EditServer::Impl {
    EditServerOptions options;
    std::unique_ptr<DeformSession> session;
    std::string modelBytes;             ///< the rest model, encoded once
    nlohmann::json graphJson;           ///< GET /api/graph
    std::map<std::string, WebFile> web; ///< by URL path

    std::mutex sessionMutex; ///< pose, save and refine take turns on the session
    std::string posedSpec;   ///< the last pose's spec (graph block made explicit), for save
    std::atomic<bool> posed{false}; ///< the session holds a pose (refine and save need one)
    std::string refinedBytes;

    std::mutex stateMutex; ///< the refine state below
    bool refining = false;
    std::string state = "idle", phase, error;
    int done = 0, total = 0;
    double elapsedMs = 0, firstProgressMs = -1;
    Stopwatch refineClock;
    std::atomic<bool> cancel{false};
    std::thread refineThread;

    httplib::Server server;
    std::thread listenThread;
    int port = 0;
    bool stopped = false;

    void loadWeb();
    void routes();
    bool allowed(const httplib::Request& req, httplib::Response& res) const;
    void guarded(httplib::Response& res, const std::function<void()>& handler);
    void pose(const httplib::Request& req, httplib::Response& res);
    void startRefine(httplib::Response& res);
    void runRefine();
    nlohmann::json progressJson();
    void save(const httplib::Request& req, httplib::Response& res);
    void refuseWhileRefining();
    fs::path saveDir(const std::string& name) const;
    void saveAnimation(const httplib::Request& req, httplib::Response& res);
};

void EditServer::Impl::loadWeb()
{
    if (options.webDir.empty()) return;
    const std::pair<const char*, const char*> files[] = {
        {"index.html", "text/html; charset=utf-8"},
        // httplib compresses text/* and exactly "application/javascript" on the fly for a browser
        // (brotli of the 2.5 MB engine: seconds per page load); with a charset it sends them as they are.
        {"editor.js", "application/javascript; charset=utf-8"},
        {"playcanvas.mjs", "application/javascript; charset=utf-8"}};
    for (const auto& [name, type] : files) {
        const fs::path path = fs::path(options.webDir) / name;
        if (!fs::is_regular_file(path)) {
            progress(msg("edit: ", path.string(), " is missing: the page will not load (scripts/setup.sh installs it)"));
            continue;
        }
        web["/" + std::string(name)] = {readWholeFile(path.string(), "editor page file"), type};
    }
    const auto index = web.find("/index.html");
    if (index == web.end()) return;
    // The page passes the token on to its scripts and API calls (a hex or [A-Za-z0-9_-] word).
    std::string& html = index->second.body;
    for (std::size_t at; (at = html.find("__TOKEN__")) != std::string::npos;) html.replace(at, 9, options.token);
    web["/"] = index->second;
}

bool EditServer::Impl::allowed(const httplib::Request& req, httplib::Response& res) const
{
    if (!hostAllowed(req.get_header_value("Host"), options.host, port)) {
        sendError(res, 403, "Host header not allowed (use http://127.0.0.1:PORT/ or http://localhost:PORT/)");
        return false;
    }
    if (!tokenMatches(requestToken(req), options.token)) {
        sendError(res, 403, "missing or wrong token (?token= or Authorization: Bearer)");
        return false;
    }
    return true;
}

void EditServer::Impl::guarded(httplib::Response& res, const std::function<void()>& handler)
{
    try {
        handler();
    } catch (const HttpError& e) {
        sendError(res, e.status, e.message);
    } catch (const InputError& e) {
        sendError(res, 400, printable(e.what()));
    } catch (const UsageError& e) {
        sendError(res, 400, printable(e.what()));
    } catch (const std::exception& e) {
        sendError(res, 500, printable(e.what()));
    }
}

void EditServer::Impl::refuseWhileRefining()
{
    const std::lock_guard<std::mutex> lock(stateMutex);
    if (refining) throw HttpError{409, "a refine is running (POST /api/cancel, or wait for GET /api/progress to say done)"};
}

void EditServer::Impl::pose(const httplib::Request& req, httplib::Response& res)
{
    // ?frame=F: the body is an animation spec (`animate --spec`); its frame F is posed, as animate would.
    const std::string text = req.has_param("frame")
                                 ? frameSpecJson(parseAnimSpec(req.body, "pose"), frameParam(req.get_param_value("frame"))).dump()
                                 : req.body;
    DeformSpec spec = parseDeformSpec(text, "pose"); // InputError: 400 with the parser's message
    nlohmann::json specJson = parseJson(text);
    refuseWhileRefining();
    const std::lock_guard<std::mutex> lock(sessionMutex);
    refuseWhileRefining(); // a refine may have started while this request waited
    posed = false; // a pose that fails leaves the session without one
    posedSpec.clear();
    refinedBytes.clear();
    // A live preview (warm-started solve, no SH rotation); refine and save pose the spec exactly.
    const DeformSession::Preview stage1 = session->preview(spec);
    specJson["graph"] = graphBlock(graphOptionsOf(spec, options.job));
    posedSpec = specJson.dump(2) + "\n";
    posed = true;
    const Stopwatch clock;
    res.set_content(encodePose(stage1.cloud, session->rest().model.shDegree), kBinary);
    res.set_header("X-Splatwarp-Solve-Ms", std::to_string(stage1.solveMs));
    res.set_header("X-Splatwarp-Update-Ms", std::to_string(stage1.updateMs));
    res.set_header("X-Splatwarp-Encode-Ms", std::to_string(clock.ms()));
    res.set_header("X-Splatwarp-Moving", std::to_string(stage1.moving));
}

void EditServer::Impl::startRefine(httplib::Response& res)
{
    if (options.job.stage1Only) throw HttpError{400, "this editor runs Stage I only (--stage1-only)"};
    {
        const std::lock_guard<std::mutex> lock(stateMutex);
        if (refining) throw HttpError{409, "a refine is already running"};
        if (!posed) throw HttpError{400, "refine needs a pose first (POST /api/pose)"};
        refining = true;
        state = "running";
        phase.clear();
        error.clear();
        done = total = 0;
        firstProgressMs = -1;
        refineClock.reset();
        cancel = false;
    }
    if (refineThread.joinable()) refineThread.join(); // the last refine's thread has finished
    refineThread = std::thread([this] { runRefine(); });
    sendJson(res, {{"state", "running"}}, 202);
}

void EditServer::Impl::runRefine()
{
    RunControl control;
    control.cancel = &cancel;
    control.onProgress = [this](const std::string& p, int d, int t) {
        const std::lock_guard<std::mutex> lock(stateMutex);
        phase = p, done = d, total = t;
        if (firstProgressMs < 0) firstProgressMs = refineClock.ms();
    };
    std::string outcome = "done", why;
    try {
        const std::lock_guard<std::mutex> lock(sessionMutex);
        refinedBytes = encodeGaussians(session->refine(control));
    } catch (const Cancelled&) {
        outcome = "cancelled";
    } catch (const std::exception& e) {
        outcome = "failed", why = printable(e.what());
    }
    const std::lock_guard<std::mutex> lock(stateMutex);
    state = outcome, error = why;
    elapsedMs = refineClock.ms();
    refining = false;
}

nlohmann::json EditServer::Impl::progressJson()
{
    const std::lock_guard<std::mutex> lock(stateMutex);
    nlohmann::json j = {{"state", state}, {"phase", phase}, {"done", done}, {"total", total},
                        {"elapsedMs", refining ? refineClock.ms() : elapsedMs}};
    if (firstProgressMs >= 0) j["firstProgressMs"] = firstProgressMs;
    if (!error.empty()) j["error"] = error;
    return j;
}

void EditServer::Impl::save(const httplib::Request& req, httplib::Response& res)
{
    nlohmann::json body;
    try {
        body = parseJson(req.body);
    } catch (const nlohmann::json::exception& e) {
        throw HttpError{400, msg("invalid JSON: ", printable(e.what()))};
    }
    if (!body.is_object() || !body.contains("name") || !body["name"].is_string() || body.size() != 1)
        throw HttpError{400, "the body must be {\"name\": \"...\"}"};
    const std::string name = body["name"].get<std::string>();
    const fs::path dir = saveDir(name);
    refuseWhileRefining();
    const std::lock_guard<std::mutex> lock(sessionMutex);
    refuseWhileRefining();
    if (!posed) throw HttpError{400, "save needs a pose first (POST /api/pose)"};
    const FrameReport report = session->write(dir.string(), {{"spec.json", posedSpec}});
    nlohmann::json reply = {{"dir", dir.string()}, {"outputs", report.outputs}};
    reply["replay"] = msg("splatwarp deform ", shellQuoted(options.job.input), " --spec ", shellQuoted((dir / "spec.json").string()),
                          " -o OUT", options.replayFlags.empty() ? "" : " ", options.replayFlags);
    sendJson(res, reply);
}

fs::path EditServer::Impl::saveDir(const std::string& name) const
{
    if (const std::string problem = saveNameProblem(name); !problem.empty()) throw HttpError{400, problem};
    if (options.job.outDir.empty()) throw HttpError{400, "this server has no output folder"};
    const fs::path dir = fs::path(options.job.outDir) / name;
    std::error_code ec;
    const fs::file_status status = fs::symlink_status(dir, ec);
    if (fs::exists(status) && !fs::is_directory(status)) // a symlink is never followed
        throw HttpError{400, msg(name, ": exists in the output folder and is not a plain folder")};
    return dir;
}

void EditServer::Impl::saveAnimation(const httplib::Request& req, httplib::Response& res)
{
    const fs::path dir = saveDir(req.get_param_value("name"));
    const AnimSpec anim = parseAnimSpec(req.body, "animation"); // 400 with the parser's message
    nlohmann::json spec = parseJson(req.body);
    const DeformSpec first = parseDeformSpec(frameSpecJson(anim, 0).dump(), "animation");
    session->checkGraph(first); // its replay runs on the session's graph, as a pose does
    spec["graph"] = graphBlock(graphOptionsOf(first, options.job));
    refuseWhileRefining(); // a 409 now, not a wait for the refine's lock
    const std::lock_guard<std::mutex> lock(sessionMutex); // one OutputSet at a time
    refuseWhileRefining();
    OutputSet outputs({options.job.input});
    outputs.createDirectory(dir.string());
    writeFileAtomic((dir / "animation.json").string(), spec.dump(2) + "\n");
    outputs.commit();
    sendJson(res, {{"file", (dir / "animation.json").string()},
                   {"replay", msg("splatwarp animate ", shellQuoted(options.job.input), " --spec ", shellQuoted((dir / "animation.json").string()),
                                  " -o OUT", options.replayFlags.empty() ? "" : " ", options.replayFlags)}});
}

void EditServer::Impl::routes()
{
    server.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response& res) {
        if (!allowed(req, res)) return httplib::Server::HandlerResponse::Handled;
        if (tooManyRanges(req.get_header_value("Range"))) {
            sendError(res, 416, "one byte range per request at most");
            return httplib::Server::HandlerResponse::Handled;
        }
        return httplib::Server::HandlerResponse::Unhandled;
    });
    for (const auto& [path, file] : web) {
        const WebFile* f = &file;
        server.Get(path, [f](const httplib::Request&, httplib::Response& res) {
            res.set_content(f->body, f->type.c_str());
        });
    }
    server.Get("/api/model", [this](const httplib::Request&, httplib::Response& res) { res.set_content(modelBytes, kBinary); });
    server.Get("/api/graph", [this](const httplib::Request&, httplib::Response& res) { sendJson(res, graphJson); });
    server.Post("/api/pose", [this](const httplib::Request& req, httplib::Response& res) { guarded(res, [&] { pose(req, res); }); });
    server.Post("/api/refine", [this](const httplib::Request&, httplib::Response& res) { guarded(res, [&] { startRefine(res); }); });
    server.Get("/api/progress", [this](const httplib::Request&, httplib::Response& res) { sendJson(res, progressJson()); });
    server.Post("/api/cancel", [this](const httplib::Request&, httplib::Response& res) {
        cancel = true;
        sendJson(res, progressJson());
    });
    server.Get("/api/refined", [this](const httplib::Request&, httplib::Response& res) {
        guarded(res, [&] {
            refuseWhileRefining();
            const std::lock_guard<std::mutex> lock(sessionMutex);
            if (refinedBytes.empty()) throw HttpError{404, "no refined model for the current pose (POST /api/refine)"};
            res.set_content(refinedBytes, kBinary);
        });
    });
    server.Post("/api/save-animation", [this](const httplib::Request& req, httplib::Response& res) {
        guarded(res, [&] { saveAnimation(req, res); });
    });
    server.Post("/api/save", [this](const httplib::Request& req, httplib::Response& res) { guarded(res, [&] { save(req, res); }); });
    server.set_exception_handler([](const httplib::Request&, httplib::Response& res, std::exception_ptr) {
        sendError(res, 500, "internal error");
    });
    server.set_error_handler([](const httplib::Request& req, httplib::Response& res) {
        if (!res.body.empty()) return;
        // Debian's compiled httplib caps form-encoded bodies (curl -d's default type) at 8 KiB.
        const bool form = req.get_header_value("Content-Type").rfind("application/x-www-form-urlencoded", 0) == 0;
        if (res.status == 413 && form)
            return sendError(res, 413, "a form-encoded body is limited to 8 KiB by the HTTP library: send it with "
                                       "Content-Type: application/json (1 MiB at most)");
        sendError(res, res.status, res.status == 413 ? "request body too large (1 MiB at most)"
                                   : res.status == 404 ? "not found"
                                                       : msg("bad request (HTTP ", res.status, "; a POST needs Content-Length, e.g. curl -d '')"));
    });
}

namespace {

nlohmann::json makeGraphJson(const DeformRest& rest, const GraphOptions& graph)
{
    nlohmann::json nodes = nlohmann::json::array();
    for (const Vec3d& p : rest.graph.nodes()) nodes.push_back({p.x, p.y, p.z});
    Vec3f lo, hi;
    centreBounds(rest.model, lo, hi);
    return {{"nodes", nodes},
            {"graph", graphBlock(graph)},
            {"gaussians", rest.model.size()},
            {"shDegree", rest.model.shDegree},
            {"bboxMin", {lo.x, lo.y, lo.z}},
            {"bboxMax", {hi.x, hi.y, hi.z}}};
}

} // namespace

EditServer::EditServer(EditServerOptions options) : mImpl(std::make_unique<Impl>())
{
    Impl& s = *mImpl;
    if (options.token.empty()) options.token = randomToken();
    if (!tokenWellFormed(options.token)) throw InputError("--token: 16 to 128 of A-Z, a-z, 0-9, '_' and '-'");
    s.options = std::move(options);
    s.session = std::make_unique<DeformSession>(s.options.job, graphSpec());
    s.modelBytes = encodeGaussians(s.session->rest().model);
    s.graphJson = makeGraphJson(s.session->rest(), graphOptionsOf(graphSpec(), s.options.job));
    s.loadWeb();
    std::error_code ec;
    if (!s.options.job.outDir.empty() && !fs::is_directory(s.options.job.outDir) &&
        !fs::create_directories(s.options.job.outDir, ec))
        throw IoError(msg(s.options.job.outDir, ": cannot create the output folder", ec ? ": " + ec.message() : ""));
}

EditServer::~EditServer() { stop(); }

int EditServer::start()
{
    Impl& s = *mImpl;
    const std::size_t threads = std::size_t(std::max(2, s.options.threads));
    s.server.new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
    s.server.set_payload_max_length(s.options.maxBodyBytes);
    s.server.set_keep_alive_timeout(1); // an idle browser connection holds a thread (and stop()) this long at most
    s.server.set_read_timeout(3, 0);    // a socket opened speculatively, sending nothing
    s.server.set_default_headers({{"Cache-Control", "no-store"},
                                  {"X-Content-Type-Options", "nosniff"},
                                  {"X-Frame-Options", "DENY"},
                                  {"Referrer-Policy", "no-referrer"}});
    s.routes();
    const std::string bindHost = s.options.host == "[::]" ? "::" : s.options.host;
    s.port = s.options.port == 0 ? s.server.bind_to_any_port(bindHost)
                                 : (s.server.bind_to_port(bindHost, s.options.port) ? s.options.port : -1);
    if (s.port <= 0) throw IoError(msg(s.options.host, ":", s.options.port, ": cannot listen there"));
    s.listenThread = std::thread([&s] { s.server.listen_after_bind(); });
    return s.port;
}

void EditServer::stop()
{
    Impl& s = *mImpl;
    if (s.stopped) return;
    s.stopped = true;
    s.cancel = true;
    if (s.listenThread.joinable()) {
        s.server.stop();
        s.listenThread.join();
    }
    if (s.refineThread.joinable()) s.refineThread.join();
}

int EditServer::port() const { return mImpl->port; }

const std::string& EditServer::token() const { return mImpl->options.token; }

std::string EditServer::url() const
{
    const std::string& host = mImpl->options.host;
    const std::string shown = isWildcardHost(host) ? "127.0.0.1" : host.find(':') != std::string::npos && host.front() != '[' ? "[" + host + "]" : host;
    return msg("http://", shown, ":", mImpl->port, "/?token=", mImpl->options.token);
}

} // namespace splatwarp::edit
