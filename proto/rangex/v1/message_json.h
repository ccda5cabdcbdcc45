// A message in protobuf's JSON mapping, with the .proto's field names and every field
// (zeros included): what `rangexctl status --json` and the HTTP API print.
#pragma once
#include <google/protobuf/message.h>

#include <string>

namespace rangex {

std::string to_json(const google::protobuf::Message& m);

}  // namespace rangex
