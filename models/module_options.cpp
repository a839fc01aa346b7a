#include "models/module_options.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdint>
#include <set>
#include <vector>

#include "data_tools/geometry/error.h"

namespace amt {
namespace {

using Json = nlohmann::json;

// Field lists: one visit() per options struct names every field once, for writing and for reading.
template <typename Visitor>
void visit(ApparelSegmenterOptions& o, Visitor&& v) {
  v("encoder_widths", o.encoder_widths);
  v("decoder_widths", o.decoder_widths);
  v("negative_slope", o.negative_slope);
  v("normalize_input", o.normalize_input);
  v("inputs", o.inputs);
}

template <typename Visitor>
void visit(SkinningPredictorOptions& o, Visitor&& v) {
  v("num_joints", o.num_joints);
  v("feature_widths", o.feature_widths);
  v("attention_widths", o.attention_widths);
  v("attention_row_context", o.attention_row_context);
  v("head_encoder_widths", o.head_encoder_widths);
  v("head_decoder_widths", o.head_decoder_widths);
  v("variant", o.variant);
  v("sort_k", o.sort_k);
  v("negative_slope", o.negative_slope);
  v("normalize_input", o.normalize_input);
}

template <typename Visitor>
void visit(ApparelDisplacementOptions& o, Visitor&& v) {
  v("num_joints", o.num_joints);
  v("motion_widths", o.motion_widths);
  v("motion_code", o.motion_code);
  v("edge_widths", o.edge_widths);
  v("decoder_widths", o.decoder_widths);
  v("negative_slope", o.negative_slope);
  v("root_relative", o.root_relative);
  v("velocity_scale", o.velocity_scale);
  v("output_scale", o.output_scale);
  v("naive_edge_conv", o.naive_edge_conv);
  v("skinned_anchor", o.skinned_anchor);
  v("zero_init", o.zero_init);
}

template <typename Visitor>
void visit(ApparelDynamicsOptions& o, Visitor&& v) {
  v("form", o.form);
  v("num_joints", o.num_joints);
  v("anchor", o.anchor);
  v("edge_widths", o.edge_widths);
  v("decoder_widths", o.decoder_widths);
  v("negative_slope", o.negative_slope);
  v("inertia", o.inertia);
  v("naive_edge_conv", o.naive_edge_conv);
  v("contact", o.contact);
  v("reach_levels", o.reach_levels);
  v("handle_spacing", o.handle_spacing);
  v("response", o.response);
  v("swing_reference", o.swing_reference);
}

template <typename Visitor>
void visit(JointRefinerOptions& o, Visitor&& v) {
  v("hidden_widths", o.hidden_widths);
  v("output_scale", o.output_scale);
  v("zero_init", o.zero_init);
}

const char* variant_name(SkinningVariant variant) {
  switch (variant) {
    case SkinningVariant::kGeodesicAttention:
      return "geodesic_attention";
    case SkinningVariant::kNoGeodesic:
      return "no_geodesic";
    case SkinningVariant::kSortByGeodesic:
      return "sort_by_geodesic";
  }
  return "unknown";
}

Json to_value(int64_t x) {
  return x;
}
Json to_value(double x) {
  return x;
}
Json to_value(bool x) {
  return x;
}
Json to_value(const std::vector<int64_t>& x) {
  return x;
}
Json to_value(const std::string& x) {
  return x;
}
Json to_value(SkinningVariant x) {
  return variant_name(x);
}

void from_value(const Json& j, const std::string& where, int64_t& out) {
  AMT_CHECK(j.is_number_integer(), where, ": expected an integer, found ", j.dump());
  out = j.get<int64_t>();
}
void from_value(const Json& j, const std::string& where, double& out) {
  AMT_CHECK(j.is_number(), where, ": expected a number, found ", j.dump());
  out = j.get<double>();
}
void from_value(const Json& j, const std::string& where, bool& out) {
  AMT_CHECK(j.is_boolean(), where, ": expected true or false, found ", j.dump());
  out = j.get<bool>();
}
void from_value(const Json& j, const std::string& where, std::vector<int64_t>& out) {
  AMT_CHECK(j.is_array(), where, ": expected an array of integers, found ", j.dump());
  std::vector<int64_t> values;
  for (const Json& x : j) {
    AMT_CHECK(x.is_number_integer(), where, ": expected an array of integers, found ", j.dump());
    values.push_back(x.get<int64_t>());
  }
  out = std::move(values);
}
void from_value(const Json& j, const std::string& where, std::string& out) {
  AMT_CHECK(j.is_string(), where, ": expected a string, found ", j.dump());
  out = j.get<std::string>();
}
void from_value(const Json& j, const std::string& where, SkinningVariant& out) {
  for (SkinningVariant v :
       {SkinningVariant::kGeodesicAttention, SkinningVariant::kNoGeodesic, SkinningVariant::kSortByGeodesic}) {
    if (j.is_string() && j.get<std::string>() == variant_name(v)) {
      out = v;
      return;
    }
  }
  fail(where, ": expected geodesic_attention, no_geodesic or sort_by_geodesic, found ", j.dump());
}

template <typename Options>
std::string write_json(const Options& options) {
  Options copy = options;  // visit() takes a mutable reference so that one field list serves both ways
  Json j = Json::object();
  visit(copy, [&j](const char* name, const auto& field) { j[name] = to_value(field); });
  return j.dump();
}

template <typename Options>
void read_json(const std::string& text, const std::string& source, Options& options) {
  const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  AMT_CHECK(j.is_object(), source, ": options: expected a JSON object, found '", text.substr(0, 80), "'");
  std::set<std::string> known;
  visit(options, [&](const char* name, auto& field) {
    known.insert(name);
    const auto it = j.find(name);
    if (it != j.end()) from_value(*it, source + ": options." + name, field);
  });
  for (const auto& item : j.items()) {
    AMT_CHECK(known.count(item.key()) != 0, source, ": options.", item.key(),
              ": unknown field (written by a newer amt?)");
  }
}

}  // namespace

std::string options_to_json(const ApparelSegmenterOptions& options) {
  return write_json(options);
}
std::string options_to_json(const SkinningPredictorOptions& options) {
  return write_json(options);
}
std::string options_to_json(const ApparelDisplacementOptions& options) {
  return write_json(options);
}
std::string options_to_json(const ApparelDynamicsOptions& options) {
  return write_json(options);
}
std::string options_to_json(const JointRefinerOptions& options) {
  return write_json(options);
}

bool is_local_apparel_options(const std::string& text) {
  const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  return j.is_object() && j.contains("form");
}

const char* skinning_variant_name(SkinningVariant variant) {
  return variant_name(variant);
}

SkinningVariant parse_skinning_variant(const std::string& name, const std::string& source) {
  if (name == "geodesic" || name == variant_name(SkinningVariant::kGeodesicAttention))
    return SkinningVariant::kGeodesicAttention;
  if (name == "no_geodesic") return SkinningVariant::kNoGeodesic;
  if (name == "sorted" || name == variant_name(SkinningVariant::kSortByGeodesic))
    return SkinningVariant::kSortByGeodesic;
  fail(source, ": expected geodesic, no_geodesic or sorted, found '", name, "'");
}

std::string skinning_file_stem(SkinningVariant variant) {
  switch (variant) {
    case SkinningVariant::kGeodesicAttention:
      return "skinning";
    case SkinningVariant::kNoGeodesic:
      return "skinning_no_geodesic";
    case SkinningVariant::kSortByGeodesic:
      return "skinning_sorted";
  }
  return "skinning";
}

void options_from_json(const std::string& text, const std::string& source, ApparelSegmenterOptions& options) {
  read_json(text, source, options);
  // A checkpoint's options hold every field; one written before the shape features read positions
  // alone. (A fragment such as --segmenter-options names a few fields and keeps the default.)
  const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  const bool complete = j.is_object() && j.contains("encoder_widths") && j.contains("decoder_widths") &&
                        j.contains("negative_slope") && j.contains("normalize_input");
  if (complete && !j.contains("inputs")) options.inputs = "positions";
  AMT_CHECK(options.inputs == "shape" || options.inputs == "welded" || options.inputs == "positions", source,
            ": options.inputs: expected \"shape\", \"welded\" or \"positions\", found \"", options.inputs, "\"");
}
void options_from_json(const std::string& text, const std::string& source, SkinningPredictorOptions& options) {
  read_json(text, source, options);
}
void options_from_json(const std::string& text, const std::string& source, ApparelDisplacementOptions& options) {
  read_json(text, source, options);
}
void options_from_json(const std::string& text, const std::string& source, ApparelDynamicsOptions& options) {
  read_json(text, source, options);
  // A checkpoint's options hold every field ("form" among them); one written before the anchor was a
  // choice anchored at the nearest body vertex. (A fragment such as --apparel-options keeps the default.)
  const Json j = Json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (j.contains("form") && !j.contains("anchor")) options.anchor = "nearest";
  // Likewise one written before the contact inputs has none.
  if (j.contains("form") && !j.contains("contact")) options.contact = false;
  if (j.contains("form") && !j.contains("reach_levels")) options.reach_levels = 0;
  if (j.contains("form") && !j.contains("handle_spacing")) options.handle_spacing = 0.0;
  AMT_CHECK(std::isfinite(options.handle_spacing) && options.handle_spacing >= 0 && options.handle_spacing <= 1, source,
            ": options.handle_spacing: expected 0 (every vertex) or a spacing in (0, 1] metres, found ",
            options.handle_spacing);
  AMT_CHECK(options.anchor == "attachment" || options.anchor == "nearest", source,
            ": options.anchor: expected \"attachment\" or \"nearest\", found \"", options.anchor, "\"");
  AMT_CHECK(options.form == "local", source, ": options.form: expected \"local\" (the apparel dynamics module), found \"",
            options.form, "\"");
}
void options_from_json(const std::string& text, const std::string& source, JointRefinerOptions& options) {
  read_json(text, source, options);
}

}  // namespace amt
