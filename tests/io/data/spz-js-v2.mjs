import { createReadStream, writeFileSync } from 'fs';
import { Readable } from 'stream';
import { loadPly, serializeSpz } from 'spz-js';
const gs = await loadPly(Readable.toWeb(createReadStream(process.argv[2])));
writeFileSync(process.argv[3], Buffer.from(await serializeSpz(gs)));
