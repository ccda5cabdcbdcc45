#include "rangex/v1/message_json.h"

#include <google/protobuf/util/json_util.h>

#include <stdexcept>

namespace rangex {

std::string to_json(const google::protobuf::Message& m) {
  std::string out;
  google::protobuf::util::JsonPrintOptions jo;
  jo.preserve_proto_field_names = true;
  jo.always_print_primitive_fields = true;
  if (!google::protobuf::util::MessageToJsonString(m, &out, jo).ok())
    throw std::runtime_error(m.GetTypeName() + " cannot be written as JSON");
  return out;
}

}  // namespace rangex
