// What every rangexctl command that talks to rangexd shares: the options, the channel (TLS
// and credentials), unary calls that cannot hang, and a decision as the commands print it.
#pragma once
#include <grpcpp/grpcpp.h>

#include <memory>
#include <set>
#include <string>

#include "args.h"
#include "channel.h"
#include "rangex/v1/rangex.pb.h"

namespace rangex::cli {

// The options of every command that talks to rangexd, beside its own.
std::set<std::string> remote_options(std::set<std::string> own);

// --server, else the configuration's listen address.
std::string server_address(const Args& a);

// The channel to rangexd. TLS and credentials: the options, else RANGEX_CA, RANGEX_CERT,
// RANGEX_KEY and RANGEX_TOKEN or RANGEX_TOKEN_FILE (a token is never an argument: `ps` would
// show it).
std::shared_ptr<grpc::Channel> server_channel(const Args& a);

// Fails with `what`, the server's message and a hint where TLS is the likely cause.
void check_status(const grpc::Status& s, const char* what);

// "NOT INSPECTED" for not_inspected; "?" for a value this build does not know.
std::string decision_text(v1::Decision d);

// One fillet's line: lane, number, uid, decision, reason and the bones found.
void print_fillet(const v1::FilletResult& f);

}  // namespace rangex::cli
