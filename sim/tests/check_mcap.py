"""Reads an mrdrive MCAP log with the official `mcap` reader and checks it.

Usage: python3 check_mcap.py LOG.mcap SCHEMA_DIR

For every channel: the schema name and encoding; one message of each is
decoded as JSON and, for Foxglove's schemas, validated with `jsonschema`
against the schema embedded in the file and the copy in SCHEMA_DIR. Prints one
line per channel and exits non-zero on the first problem.
"""
import json
import sys
from pathlib import Path

import jsonschema
from mcap.reader import make_reader


def main() -> int:
    log, schema_dir = Path(sys.argv[1]), Path(sys.argv[2])
    reference = {}
    for f in schema_dir.glob("*.json"):
        s = json.loads(f.read_text())
        reference[s["title"]] = s
    seen = {}
    with log.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        channels = {c.topic: summary.schemas[c.schema_id] for c in summary.channels.values()}
        for schema, channel, message in reader.iter_messages():
            if channel.topic in seen:
                continue
            assert schema.encoding == "jsonschema", (channel.topic, schema.encoding)
            assert channel.message_encoding == "json", channel.topic
            value = json.loads(message.data)
            embedded = json.loads(schema.data)
            jsonschema.validate(value, embedded)
            if schema.name.startswith("foxglove."):
                jsonschema.validate(value, reference[schema.name])
            seen[channel.topic] = schema.name
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
    for topic, name in sorted(channels.items()):
        status = "decoded+validated" if topic in seen else "no messages"
        print(f"{topic}\t{name.name}\t{status}")
    assert "result" in metadata and "json" in metadata["result"], "no result metadata"
    json.loads(metadata["result"]["json"])
    print(f"ok: {len(seen)} topics decoded, result metadata present")
    return 0


if __name__ == "__main__":
    sys.exit(main())
