// The v1 wire stays compatible: every message, field and enum value of a released visloc.v1
// (proto/compat/, compiled into a descriptor set at build time) is still in today's proto with
// the same number, type and cardinality, and messages written today parse in a client built
// from the released proto.

#include <google/protobuf/descriptor.h>
#include <google/protobuf/descriptor.pb.h>
#include <google/protobuf/dynamic_message.h>
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "visloc/v1/visloc.pb.h"

namespace visloc {
namespace {

namespace pb = ::google::protobuf;

class WireCompatTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::ifstream in(VISLOC_COMPAT_DESCRIPTORS, std::ios::binary);
    std::stringstream bytes;
    bytes << in.rdbuf();
    ASSERT_TRUE(released_set_.ParseFromString(bytes.str())) << VISLOC_COMPAT_DESCRIPTORS;
    for (const pb::FileDescriptorProto& file : released_set_.file()) {
      ASSERT_NE(released_.BuildFile(file), nullptr) << file.name();
    }
    released_file_ = released_.FindFileByName("visloc_v1_3f7900d.proto");
    ASSERT_NE(released_file_, nullptr);
  }

  pb::FileDescriptorSet released_set_;
  pb::DescriptorPool released_;
  const pb::FileDescriptor* released_file_ = nullptr;
  const pb::DescriptorPool* today_ = pb::DescriptorPool::generated_pool();
};

TEST_F(WireCompatTest, EveryReleasedFieldAndValueIsStillThereUnchanged) {
  ASSERT_GT(released_file_->message_type_count(), 20);
  for (int m = 0; m < released_file_->message_type_count(); ++m) {
    const pb::Descriptor* old_message = released_file_->message_type(m);
    const pb::Descriptor* message = today_->FindMessageTypeByName(old_message->full_name());
    ASSERT_NE(message, nullptr) << old_message->full_name() << " was removed";
    for (int f = 0; f < old_message->field_count(); ++f) {
      const pb::FieldDescriptor* old_field = old_message->field(f);
      const pb::FieldDescriptor* field = message->FindFieldByNumber(old_field->number());
      ASSERT_NE(field, nullptr) << old_field->full_name() << " (" << old_field->number() << ") was removed";
      EXPECT_EQ(field->type(), old_field->type()) << old_field->full_name();
      EXPECT_EQ(field->is_repeated(), old_field->is_repeated()) << old_field->full_name();
      EXPECT_EQ(field->name(), old_field->name()) << old_field->full_name();
      EXPECT_EQ(field->has_presence(), old_field->has_presence()) << old_field->full_name();
    }
  }
  for (int e = 0; e < released_file_->enum_type_count(); ++e) {
    const pb::EnumDescriptor* old_enum = released_file_->enum_type(e);
    const pb::EnumDescriptor* today = today_->FindEnumTypeByName(old_enum->full_name());
    ASSERT_NE(today, nullptr) << old_enum->full_name();
    for (int v = 0; v < old_enum->value_count(); ++v) {
      const pb::EnumValueDescriptor* value = today->FindValueByNumber(old_enum->value(v)->number());
      ASSERT_NE(value, nullptr) << old_enum->value(v)->full_name();
      EXPECT_EQ(value->name(), old_enum->value(v)->name());
    }
  }
  for (int s = 0; s < released_file_->service_count(); ++s) {
    const pb::ServiceDescriptor* old_service = released_file_->service(s);
    const pb::ServiceDescriptor* service = today_->FindServiceByName(old_service->full_name());
    ASSERT_NE(service, nullptr) << old_service->full_name();
    for (int r = 0; r < old_service->method_count(); ++r) {
      const pb::MethodDescriptor* method = service->FindMethodByName(old_service->method(r)->name());
      ASSERT_NE(method, nullptr) << old_service->method(r)->full_name();
      EXPECT_EQ(method->input_type()->full_name(), old_service->method(r)->input_type()->full_name());
      EXPECT_EQ(method->output_type()->full_name(), old_service->method(r)->output_type()->full_name());
    }
  }
}

// Today's last answer of an idle session (STATUS_CLOSED, new in this version) read by a released
// client: it parses, keeps the error text, and the unknown status value survives.
TEST_F(WireCompatTest, TodaysAnswersParseInAReleasedClient) {
  v1::LocalizeResponse closed;
  closed.set_frame_index(7);
  closed.set_status(v1::STATUS_CLOSED);
  closed.set_error("session closed: no frame for 30.0 s");
  pb::DynamicMessageFactory factory(&released_);
  const pb::Descriptor* old_type = released_.FindMessageTypeByName("visloc.v1.LocalizeResponse");
  ASSERT_NE(old_type, nullptr);
  std::unique_ptr<pb::Message> old(factory.GetPrototype(old_type)->New());
  ASSERT_TRUE(old->ParseFromString(closed.SerializeAsString()));
  const pb::Reflection* reflection = old->GetReflection();
  EXPECT_EQ(reflection->GetUInt64(*old, old_type->FindFieldByName("frame_index")), 7u);
  EXPECT_EQ(reflection->GetString(*old, old_type->FindFieldByName("error")),
            "session closed: no frame for 30.0 s");
  EXPECT_EQ(reflection->GetEnumValue(*old, old_type->FindFieldByName("status")), 8);
}

}  // namespace
}  // namespace visloc
