# gain.png from gain.csv (written by bench/pool_select_report.py); re-plot with: gnuplot gain.gp
set terminal pngcairo size 720,480 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set datafile missing 'NaN'
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'gain.png'
set title 'Panoptic basketball: gain over the control per strategy and budget'
set ylabel 'PSNR gain over the control (dB)'
set key top right
set xzeroaxis lt 1 lc rgb '#404040'
set xtics scale 0 ('fillgs' 0, 'random' 1, 'negative' 2, 'interpolation' 3, 'fisherrf' 4, 'coverage3d' 5, 'coverage4d' 6, 'positive' 7)
set xrange [-0.6:7.6]
set yrange [*<0:0<*]
set offsets 0, 0, graph 0.08, graph 0.05
plot 'gain.csv' skip 1 using ($0 - 0.4 + 0.1333):2:(0.2400) with boxes lc rgb '#3c78b4' title 'K = 10', \
     '' skip 1 using ($0 - 0.4 + 0.1333):2:3 with yerrorbars lc rgb '#404040' pt 7 ps 0 notitle, \
     'gain.csv' skip 1 using ($0 - 0.4 + 0.4000):4:(0.2400) with boxes lc rgb '#e0872c' title 'K = 30', \
     '' skip 1 using ($0 - 0.4 + 0.4000):4:5 with yerrorbars lc rgb '#404040' pt 7 ps 0 notitle, \
     'gain.csv' skip 1 using ($0 - 0.4 + 0.6667):6:(0.2400) with boxes lc rgb '#4aa04a' title 'K = 90', \
     '' skip 1 using ($0 - 0.4 + 0.6667):6:7 with yerrorbars lc rgb '#404040' pt 7 ps 0 notitle
