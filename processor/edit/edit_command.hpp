// SPDX-License-Identifier: MIT
// `pitmap edit P`: opens the session (edit_session.hpp), starts the server (edit_server.hpp) on
// 127.0.0.1, prints the page's URL with its token, opens it in the desktop's browser (xdg-open)
// unless told not to, and serves until `stop()` says so (main's signal handlers).
// Failure model: an invalid config, a survey or edit log that cannot be used, a port that
// cannot be bound: a message on stderr naming the file or address, exit status 1 (before
// serving anything). No browser to open is a note, not an error.
#pragma once

#include <functional>
#include <string>

#include "processor/edit/edit_server.hpp"
#include "processor/edit/edit_session.hpp"

namespace pitmap::proc::edit {

struct EditCommand {
    std::string out_dir;  // P
    EditSessionConfig session;
    EditServerConfig server;  // out_dir and the re-run program are set from here
    bool open_browser = true;
};

// Exit status: 0 after stop() became true, 1 on a failure before serving.
int RunEditCommand(const EditCommand& command, const std::function<bool()>& stop);

}  // namespace pitmap::proc::edit
