"""Independent reader for the tests: summarizes an MCAP file with the `mcap` package from
PyPI (not the Rust crate that wrote it). Prints one JSON object: per topic, its schema name
and encoding, the message count from the file's statistics, the count found by iterating
the messages, and how many of those parse as JSON; plus the attachments and metadata names.
Usage: python mcap_summary.py FILE.mcap"""
import json
import sys

from mcap.reader import make_reader


def main(path):
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = {}
        for c in summary.channels.values():
            schema = summary.schemas.get(c.schema_id)
            topics[c.topic] = {
                "schema": schema.name if schema else None,
                "schema_encoding": schema.encoding if schema else None,
                "message_encoding": c.message_encoding,
                "statistics_count": summary.statistics.channel_message_counts.get(c.id, 0),
                "iterated": 0,
                "json": 0,
            }
        for _schema, channel, message in reader.iter_messages():
            t = topics[channel.topic]
            t["iterated"] += 1
            try:
                json.loads(message.data)
                t["json"] += 1
            except ValueError:
                pass
        attachments = [a.name for a in reader.iter_attachments()]
        metadata = [m.name for m in reader.iter_metadata()]
    print(json.dumps({"topics": topics, "attachments": attachments, "metadata": metadata}))


if __name__ == "__main__":
    main(sys.argv[1])
