//! gRPC protocol of the crease cluster (generated from proto/crease.proto at build time, no system protoc).
