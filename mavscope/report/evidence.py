"""The report page's evidence sections (timeline, map, plots, missions, parameters, files, links): a part
of the page's template (mavscope.report.template), rendered with it, autoescape on."""

EVIDENCE = """<section id="timeline-{{ n }}">
<h2>{{ i.file.name }}: timeline of events</h2>
{% set evs = i.events.events %}
<p class="counts">{% for k, c in i.events.counts.items() %}<span>{{ k }} {{ c }}</span>{% endfor %}</p>
{% if evs %}<details{% if evs | length <= fold %} open{% endif %}><summary>{{ evs | length }} events listed</summary>
<div class="scroll"><table class="wide" id="events-{{ n }}"><thead>
<tr>
<th class="num">frame</th>
<th>time</th>
<th>kind</th>
<th>from</th>
<th>event</th></tr></thead>
<tbody>

{% for e in evs[:rows.events] %}<tr class="ev-{{ e.kind }}"><td class="num" data-label="frame" title="{{ e.show
}}">{{ e.frame }}</td>
<td data-label="time">{{ e.time | iso }}</td>
<td data-label="kind">{{ e.kind }}</td>
<td data-label="from">{{ e.from | addr }}</td>
<td data-label="event">{{ e.text }}</td></tr>
{% endfor %}</tbody></table></div>
{% if evs | length > rows.events %}<p class="more">{{ evs | length - rows.events }} more events: <code>{{
v.more.events }}</code> lists them all.</p>{% endif %}
</details>
<p class="muted">Each event's frame in full: <code>mavscope read {{ i.file.path
}} -Y 'frame.number == N' -V</code> (N: its frame).</p>
{% for k, c in i.events.dropped.items() %}<p class="more">{{ c }} {{ k
}} events were not listed by the story's bounds (a capacity finding says so).</p>{% endfor %}
{% else %}<p class="muted">No events.</p>{% endif %}
</section>

<section id="map-{{ n }}">
<h2>{{ i.file.name }}: map</h2>
{% set m = v.map %}
{% if m %}
<svg viewBox="0 0 {{ map_w }} {{ map_h
}}" role="img" aria-label="tracks, mission, fence and rally points" id="mapsvg-{{ n }}">
<rect x="0" y="0" width="{{ map_w }}" height="{{ map_h }}" fill="#f8fafc"/>
{% for s in m.shapes %}
{% if s.kind == 'fence' %}<polygon points="{{ s.points }}" fill="{{ '#fef3f2' if s.inclusion else '#fee4e2'
}}" fill-opacity="0.5" stroke="#b42318" stroke-width="1.5" stroke-dasharray="6 3"><title>{{ s.name
}}</title></polygon>
{% elif s.kind == 'fence-circle' %}<circle cx="{{ s.x }}" cy="{{ s.y }}" r="{{ s.r
}}" fill="none" stroke="#b42318" stroke-width="1.5" stroke-dasharray="6 3"><title>{{ s.name }}</title></circle>
{% elif s.kind == 'track' %}<polyline class="track{{ s.colour % 4 }}" points="{{ s.points
}}" fill="none" stroke-width="2"><title>{{ s.name }}</title></polyline>
{% elif s.kind == 'mission' %}<polyline points="{{ s.points
}}" fill="none" stroke="#6941c6" stroke-width="1.5" stroke-dasharray="4 3"><title>{{ s.name }}</title></polyline>
{% endif %}{% endfor %}
{% for s in m.shapes %}
{% if s.kind == 'waypoint' %}<circle cx="{{ s.x }}" cy="{{ s.y }}" r="4" fill="#6941c6"><title>{{ s.name
}}</title></circle><text x="{{ s.x + 6 }}" y="{{ s.y - 5 }}">{{ s.name.split(' ')[0] }}</text>
{% elif s.kind == 'home' %}<rect x="{{ s.x - 5 }}" y="{{ s.y - 5
}}" width="10" height="10" fill="#067647"><title>home</title></rect><text x="{{ s.x + 7 }}" y="{{ s.y + 4 }}">H</text>
{% elif s.kind == 'rally' %}<polygon points="{{ s.x }},{{ s.y - 6 }} {{ s.x + 6 }},{{ s.y + 5 }} {{ s.x - 6 }},{{
s.y + 5 }}" fill="#b54708"><title>{{ s.name }}</title></polygon>
{% elif s.kind == 'track' and not s.points %}<circle cx="{{ s.x }}" cy="{{ s.y }}" r="3" class="track{{ s.colour % 4
}}" fill="none" stroke-width="2"><title>{{ s.name }}</title></circle>
{% endif %}{% endfor %}
<g transform="translate({{ map_w - 34
}},16)"><polygon points="0,0 7,20 0,15 -7,20" fill="#1b1f24"/><text x="-4" y="34">N</text></g>
<g transform="translate(16,{{ map_h - 18 }})"><rect x="0" y="-4" width="{{ m.scale_px
}}" height="4" fill="#1b1f24"/><text x="0" y="12">0</text><text x="{{ m.scale_px }}" y="12" text-anchor="end">{{
m.scale_text }}</text></g>
</svg>
<p class="legend">
<span><i class="sw" style="background:#175cd3"></i>track</span>
<span><i class="sw" style="background:#6941c6"></i>mission</span>
<span><i class="sw" style="background:#b42318"></i>fence</span>
<span><i class="sw" style="background:#b54708"></i>rally</span>
<span><i class="sw" style="background:#067647"></i>home</span></p>
{% set trs = i.map.features | selectattr('properties.kind', 'equalto', 'track') | list %}
<ul>{% for f in trs[:rows.systems] %}<li>{{ f.properties.name }}: {{ "{:,}".format(f.properties.positions) }}
positions{%
if f.properties.every > 1 %} (every {{ f.properties.every }}th kept){% endif %}</li>{% endfor %}</ul>
{% if trs | length > rows.systems %}<p class="more">{{ trs | length - rows.systems }} more tracks: <code>mavscope track
{{ i.file.path }} --geojson OUT</code> writes them all.</p>{% endif %}
{% for k, c in m.left_out | dictsort %}<p class="more">{{ c }} {{ k }} features not drawn (the drawing keeps the tracks
of the most positions and the first of each other kind; the JSON report holds every one).</p>{% endfor %}
<p class="muted">North up, equirectangular about the middle latitude; no map tiles. The same features:
<code>mavscope track {{ i.file.path }} --geojson OUT</code>.</p>
{% else %}<p class="muted">No position in the capture (GLOBAL_POSITION_INT, GPS_RAW_INT with a fix) and no mission,
fence or rally point.</p>{% endif %}
</section>

<section id="plots-{{ n }}">
<h2>{{ i.file.name }}: plots</h2>
<p class="muted">Per pixel column the minimum and the maximum of the values in it (the band), over seconds from the
first frame.</p>
{% for p in v.plots + [v.signing] %}
<figure class="plot" data-field="{{ p.title }}">
<h3>{{ p.title }}{% if p.unit %} ({{ p.unit }}){% endif %}</h3>
{% if p.count %}
<div class="scroll"><svg viewBox="0 0 {{ plot_w }} {{ plot_h }}" role="img" aria-label="{{ p.title }}">
{% for y, label in p.y_ticks %}<line x1="{{ pad_l }}" x2="{{ plot_w }}" y1="{{ y }}" y2="{{ y
}}" stroke="#eaecf0"/><text x="{{ pad_l - 4 }}" y="{{ y + 4 }}" text-anchor="end">{{ label }}</text>
{% endfor %}
{% for x, label in p.x_ticks %}<text x="{{ x }}" y="{{ plot_h - 6 }}" text-anchor="middle">{{ label }}</text>
{% endfor %}
{% for x, what in p.marks %}<line x1="{{ x }}" x2="{{ x }}" y1="4" y2="{{ plot_h - pad_b
}}" stroke="#b42318" stroke-dasharray="3 2"><title>{{ what }}</title></line>
{% endfor %}
{% if p.envelope %}<polygon points="{{ p.envelope }}" fill="#175cd3" fill-opacity="0.25" stroke="none"/>
<polyline points="{{ p.upper }}" fill="none" stroke="#175cd3" stroke-width="1"/><polyline points="{{ p.lower
}}" fill="none" stroke="#175cd3" stroke-width="1"/>{% endif %}
{% for x, y in p.dots %}<circle cx="{{ x }}" cy="{{ y }}" r="2.5" fill="#175cd3"/>
{% endfor %}
{% for name, pts in p.lines %}<polyline points="{{ pts }}" fill="none" stroke="{{ colours.get(name, '#344054')
}}" stroke-width="1.5"><title>{{ name }}</title></polyline>
{% endfor %}
</svg></div>
{% if p.lines %}<p class="legend">{% for name, pts in p.lines %}<span><i class="sw" style="background:{{
colours.get(name, '#344054') }}"></i>{{ name }}</span>{% endfor %}{% if p.marks
%}<span><i class="sw" style="background:#b42318"></i>link lost / heard again ({{ p.marks | length }})</span>{% endif
%}</p>
{% else %}<p class="muted">{{ "{:,}".format(p.count) }} values, from {{ '%.6g' | format(p.low) }} to {{ '%.6g' |
format(p.high) }}.</p>{% endif %}
{% else %}<p class="muted">No values in the capture.</p>{% endif %}
</figure>
{% endfor %}
</section>

<section id="missions-{{ n }}">
<h2>{{ i.file.name }}: missions</h2>
{% set ts = i.missions.transfers %}
{% if ts %}
{% for p in i.missions.progress %}<p>Vehicle {{ p.sysid }}: reached items {{ p.reached[:60] | join(', ') or 'none'
}}{% if p.reached | length > 60 %} and {{ p.reached | length - 60 }} more{% endif %}; was on items {{ p.current[:60]
| join(', ') or 'none' }}{% if p.current | length > 60 %} and {{ p.current | length - 60 }} more{% endif %}.</p>{%
endfor %}
<details{% if ts | length <= fold %} open{% endif %}><summary>{{ ts | length }} transfers</summary>
<div class="scroll"><table class="wide" id="transfers-{{ n }}"><thead>
<tr>
<th class="num">#</th>
<th>what</th>
<th>from, to</th>
<th class="num">items</th>
<th>outcome</th>
<th>reached after it</th>
<th>frames</th></tr></thead>
<tbody>

{% for t in ts[:rows.transfers] %}<tr>
<td class="num" data-label="#">{{ t.transfer }}</td>
<td data-label="what">{{ t.direction }} {{ t.mission_type }}</td>
<td data-label="from, to" class="nowrap">{{ t.from | addr }} &rarr; {{ t.to | addr }}</td>
<td class="num" data-label="items">{{ t['items'] | length }} of {{ t.count }}</td>
<td data-label="outcome">{{ t.outcome }}: {{ t.reason }}</td>
<td data-label="reached after it">{% if t.reached is defined %}{{ t.reached | length }} of {{ t['items'] | length
}}{% endif %}</td>
<td data-label="frames">{% if t.frames %}{{ t.frames[0] }} to {{ t.frames[1] }}{% endif %}</td></tr>
{% endfor %}</tbody></table></div>
{% if ts | length > rows.transfers %}<p class="more">{{ ts | length - rows.transfers }} more: <code>{{
v.more.missions }}</code> lists them all.</p>{% endif %}</details>
{% set shown = ts | selectattr('direction', 'equalto', 'upload') | selectattr('items') | list %}
{% for t in shown[-rows.uploads:] %}
<details{% if loop.last %} open{% endif %}><summary>Transfer {{ t.transfer }}: upload of {{ t['items'] | length
}} {{ t.mission_type }} items to {{ t.to | addr }}, {{ t.outcome }}; started {{ t.start | iso }}</summary>
<div class="scroll"><table class="wide"><thead>
<tr>
<th class="num">seq</th>
<th>command</th>
<th class="num">x / lat</th>
<th class="num">y / lon</th>
<th class="num">z</th>
<th>reached</th>
<th class="num">frame</th></tr></thead>
<tbody>

{% for it in t['items'][:rows['items']] %}<tr>
<td class="num" data-label="seq">{{ it.seq }}</td>
<td data-label="command">{{ it.command }}</td>
<td class="num" data-label="x / lat">{{ it.x }}</td>
<td class="num" data-label="y / lon">{{ it.y }}</td>
<td class="num" data-label="z">{{ it.z }}</td>
<td data-label="reached">{{ 'yes' if t.reached is defined and it.seq in t.reached else '' }}</td>
<td class="num" data-label="frame">{{ it.frame }}</td></tr>
{% endfor %}</tbody></table></div>
{% if t['items'] | length > rows['items'] %}<p class="more">{{ t['items'] | length - rows['items'] }} more: <code>{{
v.more.missions }}</code></p>{% endif %}</details>
{% endfor %}
{% if shown | length > rows.uploads %}<p class="more">The items of the last {{ rows.uploads }} of {{ shown | length
}} uploads are shown: <code>{{ v.more.missions }}</code> lists every one.</p>{% endif %}
{% else %}<p class="muted">No mission, fence or rally transfer.</p>{% endif %}
</section>

<section id="params-{{ n }}">
<h2>{{ i.file.name }}: parameters</h2>
{% set ch = i.params.changes %}
<p>{{ ch | length }} sets and changes; {{ i.params.final_count }} final values{% if i.params.main_component %} of {{
i.params.main_component | addr }}{% endif %}.</p>
{% if ch %}<details{% if ch | length <= fold %} open{% endif %}><summary>{{ ch | length }} sets and changes</summary>
<div class="scroll"><table class="wide" id="params-table-{{ n }}"><thead>
<tr>
<th class="num">frame</th>
<th>time</th>
<th>who</th>
<th>parameter</th>
<th>value</th>
<th>was</th>
<th>confirmed</th>
<th>signature</th></tr></thead>
<tbody>

{% for c in ch[:rows.params] %}<tr>
<td class="num" data-label="frame">{{ c.frame }}</td>
<td data-label="time">{{ c.time | iso }}</td>
<td data-label="who">{{ c.from | addr }}{% if c.to %} to {{ c.to | addr }}{% endif %}</td>
<td data-label="parameter">{{ c.name }}{% if c.security %} <b title="security-relevant">!</b>{% endif %}</td>
<td data-label="value">{{ c.value }}</td>
<td data-label="was">{{ c.previous if c.previous is not none else '' }}</td>
<td data-label="confirmed">{{ {True: 'yes', False: 'no'}.get(c.confirmed, 'no answer') if c.what == 'set' else
'change' }}</td>
<td data-label="signature">{{ c.signature }}</td></tr>
{% endfor %}</tbody></table></div>
{% if ch | length > rows.params %}<p class="more">{{ ch | length - rows.params }} more: <code>{{ v.more.params
}}</code></p>{% endif %}</details>{% endif %}
{% if i.params.get('diff') %}{% set d = i.params['diff'] %}
<h3>Compared with {{ d.other }}</h3>
<p>{{ d.changed | length }} changed, {{ d.only_here | length }} only in the capture, {{ d.only_there | length
}} only in the file.</p>
{% if d.changed or d.only_here or d.only_there %}<details{% if (d.changed | length) + (d.only_here | length) +
(d.only_there | length) <= fold %} open{% endif %}><summary>the differences</summary>
<div class="scroll"><table class="wide" id="paramdiff-{{ n }}"><thead>
<tr>
<th>parameter</th>
<th>capture</th>
<th>file</th>
<th>security</th></tr></thead>
<tbody>

{% for name, pair in d.changed.items() %}<tr>
<td data-label="parameter">{{ name }}</td>
<td data-label="capture">{{ pair[0] }}</td>
<td data-label="file">{{ pair[1] }}</td>
<td data-label="security">{{ d.security.get(name, '') }}</td></tr>{% endfor %}
{% for name, value in d.only_here.items() %}<tr>
<td data-label="parameter">{{ name }}</td>
<td data-label="capture">{{ value }}</td>
<td data-label="file">-</td>
<td data-label="security">{{ d.security.get(name, '') }}</td></tr>{% endfor %}
{% for name, value in d.only_there.items() %}<tr>
<td data-label="parameter">{{ name }}</td>
<td data-label="capture">-</td>
<td data-label="file">{{ value }}</td>
<td data-label="security">{{ d.security.get(name, '') }}</td></tr>{% endfor %}
</tbody></table></div></details>{% endif %}
{% endif %}
</section>

<section id="files-{{ n }}">
<h2>{{ i.file.name }}: files moved</h2>
{% set fs = i.files %}
{% if fs %}<details{% if fs | length <= fold %} open{% endif %}><summary>{{ fs | length
}} objects (MAVLink FTP, logs, images)</summary>
<div class="scroll"><table class="wide" id="files-table-{{ n }}"><thead>
<tr>
<th class="num">frame</th>
<th>kind</th>
<th>path / name</th>
<th>from, to</th>
<th class="num">size</th>
<th>complete</th>
<th>SHA-256</th></tr></thead>
<tbody>

{% for f in fs[:rows.files] %}<tr>
<td class="num" data-label="frame">{{ f.frame }}</td>
<td data-label="kind">{{ f.object }} {{ f.direction }}</td>
<td data-label="path / name"><code class="path">{{ f.path if f.path is not none else f.name }}</code>{% if
f.runs_as_code %} <b>runs as code</b>{% endif %}</td>
<td data-label="from, to">{{ f.from | addr }}, {{ f.to | addr }}</td>
<td class="num" data-label="size">{{ f.size | size }}</td>
<td data-label="complete">{{ 'yes' if f.complete else 'no' }}</td>
<td data-label="SHA-256"><code>{{ f.sha256 }}</code></td></tr>
{% endfor %}</tbody></table></div>
{% if fs | length > rows.files %}<p class="more">{{ fs | length - rows.files }} more: <code>{{ v.more.files
}}</code></p>{% endif %}</details>
{% else %}<p class="muted">No file, log or image moved.</p>{% endif %}
</section>

<section id="links-{{ n }}">
<h2>{{ i.file.name }}: links</h2>
{% set t = i.stats.totals %}
<p>{{ "{:,}".format(t.frames) }} frames, {{ t.bytes | size }}, {{ t.links }} links, {{ t.messages
}} message types; {{ t.lost }} lost; MAVLink v1 {{ t.v1 }}, v2 {{ t.v2 }}; CRC {{ t.crc | counts }}; signatures {{
t.signature | counts }}.</p>
{% set lks = i.stats.links %}
<details{% if lks | length <= fold %} open{% endif %}><summary>{{ lks | length }} links (sysid, compid)</summary>
<div class="scroll"><table class="wide" id="links-table-{{ n }}"><thead>
<tr>
<th>sender</th>
<th class="num">received</th>
<th class="num">lost</th>
<th class="num">loss %</th>
<th class="num">dup</th>
<th>CRC</th>
<th>signature</th>
<th>endpoints</th></tr></thead>
<tbody>

{% for l in lks[:rows.links] %}<tr>
<td data-label="sender">{{ l.sysid }}/{{ l.compid }}</td>
<td class="num" data-label="received">{{ "{:,}".format(l.received) }}</td>
<td class="num" data-label="lost">{{ l.lost }}</td>
<td class="num" data-label="loss %">{{ l.loss_pct }}</td>
<td class="num" data-label="dup">{{ l.duplicates }}</td>
<td data-label="CRC">{{ l.crc | counts }}</td>
<td data-label="signature">{{ l.signature | counts }}</td>
<td data-label="endpoints">{{ l.endpoints[:4] | join(', ') }}{% if l.endpoints | length > 4 %} and {{ l.endpoints |
length - 4 }} more{% endif %}</td></tr>
{% endfor %}</tbody></table></div>
{% if lks | length > rows.links %}<p class="more">{{ lks | length - rows.links }} more: <code>{{ v.more.links
}}</code></p>{% endif %}</details>
{% set ms = i.stats.messages %}
<details><summary>{{ ms | length }} message streams</summary>
<div class="scroll"><table class="wide" id="messages-table-{{ n }}"><thead>
<tr>
<th>sender</th>
<th>message</th>
<th class="num">count</th>
<th class="num">rate Hz</th>
<th class="num">bytes</th></tr></thead>
<tbody>

{% for m in ms[:rows.messages] %}<tr>
<td data-label="sender">{{ m.sysid }}/{{ m.compid }}</td>
<td data-label="message">{{ m.msgname }}</td>
<td class="num" data-label="count">{{ "{:,}".format(m.count) }}</td>
<td class="num" data-label="rate Hz">{{ 'burst' if m.burst else m.rate_hz }}</td>
<td class="num" data-label="bytes">{{ "{:,}".format(m.bytes) }}</td></tr>
{% endfor %}</tbody></table></div>
{% if ms | length > rows.messages %}<p class="more">{{ ms | length - rows.messages }} more: <code>{{ v.more.links
}}</code></p>{% endif %}</details>
</section>
</article>
{% endfor %}
"""
