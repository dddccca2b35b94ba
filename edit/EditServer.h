#pragma once
/// @file EditServer.h
/// @brief `splatwarp edit`'s server: a DeformSession behind a small HTTP API on loopback
///        (docs/editor-api.md), and the page's files. Every request needs the run's token and a
///        Host header naming this server; bodies are bounded; saves go to single folders inside
///        the output directory; one refine runs at a time, in its own thread.
#include <cstddef>
#include <memory>
#include <string>

#include "job/DeformPipeline.h"

namespace splatwarp::edit {

/// @brief How the server is set up.
struct EditServerOptions {
    /// The model (job.input) and every deform setting; job.outDir is the folder saves go into
    /// (created at start; empty: saves are refused). Saved runs equal `deform --spec DIR/NAME/spec.json` with these settings.
    DeformJobOptions job;
    std::string host = "127.0.0.1"; ///< address to bind; a wildcard only when the user asks
    int port = 0;                   ///< 0: a free port
    std::string token;              ///< required on every request (randomToken() when empty)
    std::string webDir;             ///< index.html, editor.js, playcanvas.mjs (read once at start); empty: API only
    std::size_t maxBodyBytes = std::size_t(1) << 20; ///< larger request bodies get 413
    /// HTTP worker threads. A thread serves one connection for its keep-alive life, and a browser
    /// opens several (some speculatively, sending nothing): too few threads and a page's requests
    /// queue behind idle sockets for seconds (seen with 4).
    int threads = 32;
    /// Flags to repeat after `deform MODEL --spec spec.json -o OUT` to replay a save (the save's reply says it).
    std::string replayFlags;
};

/// @brief The editor's server. The constructor prepares the rest side (slow: reads the model,
///        builds the graph and the sample grid); start() binds and serves in a thread.
class EditServer {
public:
    /// @throws InputError / IoError as DeformSession; InputError for a malformed --token.
    explicit EditServer(EditServerOptions options);
    ~EditServer();
    EditServer(const EditServer&) = delete;
    EditServer& operator=(const EditServer&) = delete;

    /// @brief Bind host:port and serve in a background thread; returns the bound port.
    /// @throws IoError when the address cannot be bound.
    int start();
    /// @brief Cancel a running refine, stop serving, join every thread (idempotent).
    void stop();

    int port() const;
    const std::string& token() const;
    /// @brief http://HOST:PORT/?token=T (127.0.0.1 for a wildcard bind).
    std::string url() const;

private:
    struct Impl;
    std::unique_ptr<Impl> mImpl;
};

} // namespace splatwarp::edit
