# paired_table1.png from paired_table1.csv (written by fillgs); re-plot with: gnuplot paired_table1.gp
set terminal pngcairo size 900,548 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'paired_table1.png'
set title 'FillGS minus each (n3v): mean and 95 % interval over paired seeds; filled: excludes 0'
set xlabel 'PSNR difference (dB; x.w-none rows: FillGS''s unweighted row minus x''s)'
set ylabel ''
set key outside right top vertical
unset grid
set grid xtics lc rgb '#dddddd' lt 1
set yrange [11.5:-0.5]
set ytics scale 0
set ytics ('random.w-none@oracle' 0, 'random@oracle' 1, 'negative@oracle' 2, 'interpolation@oracle' 3, 'fisherrf@oracle' 4, 'coverage3d@oracle' 5, 'coverage4d@oracle' 6, 'coverage4d.w-none@oracle' 7, 'negative.w-none@oracle' 8, 'interpolation.w-none@oracle' 9, 'fisherrf.w-none@oracle' 10, 'coverage3d.w-none@oracle' 11)
set xrange [-7.67463127:7.67463127]
set arrow from 0, graph 0 to 0, graph 1 nohead dt 2 lc rgb '#404040'
plot 'paired_table1.csv' skip 1 using ($1 == 0 && $6 > 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt 7 ps 1.3 lw 2 lc rgb '#3c78b4' title 'interpolation', \
     'paired_table1.csv' skip 1 using ($1 == 0 && $6 < 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt 6 ps 1.3 lw 2 lc rgb '#3c78b4' notitle, \
     'paired_table1.csv' skip 1 using ($1 == 1 && $6 > 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt 7 ps 1.3 lw 2 lc rgb '#e0872c' title 'extrapolation', \
     'paired_table1.csv' skip 1 using ($1 == 1 && $6 < 0.5 ? $3 : NaN):2:4:5 with xerrorbars pt 6 ps 1.3 lw 2 lc rgb '#e0872c' notitle
